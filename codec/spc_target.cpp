// The target search of .spc format 2 against the lighting suite.
#include "specula/codec/spc_target.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>

#include "specula/codec/spc_detail.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

// One trial coding: its step, the suite's verdict and its excess, the largest ratio of a measure to its limit (the
// target is met at <= 1).
struct Trial {
  double step = 0;
  double excess = 0;
  SuiteDiff diff;
};

void check_target(const SpcTarget& t) {
  for (const double v : {t.de00_mean, t.de00_p95, t.condition_mean})
    if (!(std::isfinite(v) && v > 0))
      throw UsageError("target: de00_mean, de00_p95 and condition_mean must be positive");
  if (t.max_trials < 2 || t.max_trials > 32) throw UsageError("target: max_trials must be 2 to 32");
  if (!(std::isfinite(t.first_step) && t.first_step > 0 && t.first_step <= 10))
    throw UsageError("target: first_step must be in (0, 10]");
}

// The next step to try from the trials so far, or nothing when the search is over. The suite's error grows about
// in proportion to the step, so each next step aims at an excess of 0.95: scaled from a single trial (by 2 to 16
// times), then by interpolating log excess against log step inside the bracket (kept a tenth of the bracket away
// from its ends), until the bracket is within 20 %.
std::optional<double> next_step(const std::optional<Trial>& good, const std::optional<Trial>& bad, double finest) {
  constexpr double kAim = 0.95;
  if (good && bad) {
    if (bad->step / good->step <= 1.2) return std::nullopt;
    const double xg = std::log(good->step), xb = std::log(bad->step);
    const double yg = std::log(std::max(good->excess, 1e-6)), yb = std::log(bad->excess);
    double x = yb > yg ? xg + (std::log(kAim) - yg) * (xb - xg) / (yb - yg) : 0.5 * (xg + xb);
    x = std::clamp(x, xg + 0.1 * (xb - xg), xb - 0.1 * (xb - xg));
    return std::exp(x);
  }
  if (good) {
    const double step = good->step * std::clamp(kAim / std::max(good->excess, 1e-6), 2.0, 16.0);
    return step > 10 ? std::nullopt : std::optional<double>(step);
  }
  if (bad->step <= finest) return std::nullopt;  // out of reach: the basis or the float channels limit it
  return std::max(finest, bad->step / std::clamp(bad->excess / kAim, 2.0, 16.0));
}

// One trial coding at `step`, judged by the suite against the reference's renders; decoded into `scratch`, whose
// storage the trials of a search share (a fresh grid's pages cost as much to fault in as the suite to render).
Trial run_trial(const detail::StepCoder& model, const SuiteRenders& reference, const LightingSuite& suite,
                const SpcTarget& target, double step, store::Grid& scratch) {
  model.decoded(step, scratch);
  Trial t{step, 0, suite.compare(reference, suite.render(scratch))};
  t.excess = std::max({t.diff.de00_mean / target.de00_mean, t.diff.de00_p95 / target.de00_p95,
                       t.diff.conditions[t.diff.worst].de00_mean / target.condition_mean});
  return t;
}

// The step search of encode_spc_to_target from `first_step`: the trial coded, whether it met the target, and
// how many trials it took.
struct Search {
  Trial chosen;
  bool reached = false;
  int trials = 0;
};

Search search_step(const detail::StepCoder& model, const SuiteRenders& reference, const LightingSuite& suite,
                   const SpcTarget& target, double first_step, store::Grid& scratch) {
  std::optional<Trial> good, bad;
  const double finest = std::max(1e-6, model.finest_step());
  std::optional<double> step = std::max(first_step, finest);
  int trials = 0;
  while (step && trials < target.max_trials) {
    Trial t = run_trial(model, reference, suite, target, *step, scratch);
    ++trials;
    (t.excess <= 1 ? good : bad) = std::move(t);
    step = next_step(good, bad, finest);
  }
  return {good ? std::move(*good) : std::move(*bad), good.has_value(), trials};
}

void fill_report(const Search& s, const LightingSuite& suite, SpcTargetReport& tr) {
  tr = {};
  tr.reached = s.reached;
  tr.trials = s.trials;
  tr.step = s.chosen.step;
  tr.de00_mean = s.chosen.diff.de00_mean;
  tr.de00_p95 = s.chosen.diff.de00_p95;
  tr.worst_mean = s.chosen.diff.conditions[s.chosen.diff.worst].de00_mean;
  tr.worst_condition = suite.conditions()[s.chosen.diff.worst].name;
}

// A basis of the family and its coder (the model refers to the basis, so both live here).
struct Coder {
  std::unique_ptr<SpcBasis> basis;
  std::unique_ptr<detail::StepCoder> model;
};

// The coder of a basis, for each k a search over k tries.
using CoderOfK = std::function<Coder(std::size_t k)>;

// The k search of encode_spc_choosing_k over any coder family, judged against `reference`'s renders.
std::vector<std::uint8_t> choose_k(const SuiteRenders& reference, const CoderOfK& coder_of_k, std::size_t k_max,
                                   const SpcTarget& target, const LightingSuite& suite, SpcTargetReport& tr,
                                   SpcKReport& kr, SpcBasis* chosen_basis, SpcReport* report,
                                   const std::string& source);

}  // namespace

std::vector<std::uint8_t> encode_spc_to_target(const store::Grid& grid, const SpcBasis& basis,
                                               const SpcTransformOptions& o, const SpcTarget& target,
                                               const LightingSuite& suite, SpcTargetReport& tr, SpcReport* report,
                                               const std::string& source) {
  check_target(target);
  const detail::TransformModel model(grid, basis, o);
  store::Grid scratch;
  const Search s = search_step(model, suite.render(grid), suite, target, target.first_step, scratch);
  fill_report(s, suite, tr);
  return model.code(s.chosen.step, report, source);
}

std::vector<std::uint8_t> encode_spc_choosing_k(const store::Grid& grid, const SpcBasisOfK& basis_of_k,
                                                std::size_t k_max, const SpcTransformOptions& o,
                                                const SpcTarget& target, const LightingSuite& suite,
                                                SpcTargetReport& tr, SpcKReport& kr, SpcBasis* chosen_basis,
                                                SpcReport* report, const std::string& source) {
  check_target(target);
  const CoderOfK coder_of_k = [&](std::size_t k) {
    Coder c;
    c.basis = std::make_unique<SpcBasis>(basis_of_k(k));
    c.model = std::make_unique<detail::TransformModel>(grid, *c.basis, o);
    return c;
  };
  return choose_k(suite.render(grid), coder_of_k, k_max, target, suite, tr, kr, chosen_basis, report, source);
}

std::vector<std::uint8_t> encode_spc_samples_choosing_k(const SpcSampleSet& samples, const store::Grid& reference,
                                                        const SpcBasisOfK& basis_of_k, std::size_t k_max,
                                                        const SpcSamplesOptions& o, const SpcTarget& target,
                                                        const LightingSuite& suite, SpcTargetReport& tr, SpcKReport& kr,
                                                        SpcBasis* chosen_basis, SpcReport* report,
                                                        const std::string& source) {
  check_target(target);
  const CoderOfK coder_of_k = [&](std::size_t k) {
    Coder c;
    c.basis = std::make_unique<SpcBasis>(basis_of_k(k));
    c.model = std::make_unique<detail::SamplesModel>(samples, *c.basis, o, reference);
    return c;
  };
  return choose_k(suite.render(reference), coder_of_k, k_max, target, suite, tr, kr, chosen_basis, report, source);
}

namespace {

std::vector<std::uint8_t> choose_k(const SuiteRenders& reference, const CoderOfK& coder_of_k, std::size_t k_max,
                                   const SpcTarget& target, const LightingSuite& suite, SpcTargetReport& tr,
                                   SpcKReport& kr, SpcBasis* chosen_basis, SpcReport* report,
                                   const std::string& source) {
  if (k_max < 1) throw UsageError("k search: the largest k must be at least 1");
  kr = {};
  // Floors, by bisection: hi ends as the smallest k meeting the target at the finest step, or k_max (its coder kept).
  Coder kept;
  store::Grid scratch;
  auto floor_met = [&](std::size_t k) {
    Coder c = coder_of_k(k);
    const bool met =
        run_trial(*c.model, reference, suite, target, std::max(1e-6, c.model->finest_step()), scratch).excess <= 1;
    kr.candidates.push_back({.k = k, .floor_met = met});
    if (met) kept = std::move(c);
    return met;
  };
  std::size_t lo = 1, hi = k_max;  // k_max is not probed: if no smaller k meets it, it is searched regardless
  while (lo < hi) {
    const std::size_t mid = lo + (hi - lo) / 2;
    if (floor_met(mid))
      hi = mid;
    else
      lo = mid + 1;
  }
  // Sizes, upwards from the floor, until two successive k give no smaller file.
  std::vector<std::uint8_t> best;
  bool best_reached = false;
  SpcReport best_report;
  std::unique_ptr<SpcBasis> best_basis;
  double first = target.first_step;
  for (std::size_t k = hi, misses = 0; k <= k_max && misses < 2; ++k) {
    Coder c = kept.model ? std::move(kept) : coder_of_k(k);
    const Search s = search_step(*c.model, reference, suite, target, first, scratch);
    SpcReport rep;
    auto bytes = c.model->code(s.chosen.step, &rep, source);
    kr.candidates.push_back({.k = k,
                             .searched = true,
                             .reached = s.reached,
                             .first_step = first,
                             .step = s.chosen.step,
                             .bytes = bytes.size()});
    const bool better = s.reached ? !best_reached || bytes.size() < best.size() : best.empty();
    if (better) {
      best = std::move(bytes);
      best_reached = s.reached;
      best_report = rep;
      best_basis = std::move(c.basis);
      kr.k = k;
      fill_report(s, suite, tr);
    }
    misses = better ? 0 : misses + 1;
    if (s.reached) first = std::min(s.chosen.step, 10.0);
  }
  if (report) *report = best_report;
  if (chosen_basis) *chosen_basis = *best_basis;
  return best;
}

}  // namespace

}  // namespace specula::codec
