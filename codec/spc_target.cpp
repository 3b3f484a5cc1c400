// The target search of .spc format 2 against the lighting suite.
#include "specula/codec/spc_target.h"

#include <algorithm>
#include <cmath>
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

}  // namespace

std::vector<std::uint8_t> encode_spc_to_target(const store::Grid& grid, const SpcBasis& basis,
                                               const SpcTransformOptions& o, const SpcTarget& target,
                                               const LightingSuite& suite, SpcTargetReport& tr, SpcReport* report,
                                               const std::string& source) {
  check_target(target);
  const detail::TransformModel model(grid, basis, o);
  const SuiteRenders reference = suite.render(grid);
  tr = {};
  auto trial = [&](double step) {
    Trial t{step, 0, suite.compare(reference, suite.render(model.decoded(step)))};
    t.excess = std::max({t.diff.de00_mean / target.de00_mean, t.diff.de00_p95 / target.de00_p95,
                         t.diff.conditions[t.diff.worst].de00_mean / target.condition_mean});
    ++tr.trials;
    return t;
  };
  std::optional<Trial> good, bad;
  const double finest = std::max(1e-6, model.finest_step());
  std::optional<double> step = std::max(target.first_step, finest);
  while (step && tr.trials < target.max_trials) {
    Trial t = trial(*step);
    (t.excess <= 1 ? good : bad) = std::move(t);
    step = next_step(good, bad, finest);
  }
  const Trial& chosen = good ? *good : *bad;
  tr.reached = good.has_value();
  tr.step = chosen.step;
  tr.de00_mean = chosen.diff.de00_mean;
  tr.de00_p95 = chosen.diff.de00_p95;
  tr.worst_mean = chosen.diff.conditions[chosen.diff.worst].de00_mean;
  tr.worst_condition = suite.conditions()[chosen.diff.worst].name;
  return model.code(chosen.step, report, source);
}

}  // namespace specula::codec
