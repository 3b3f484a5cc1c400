#include "specula/acquire/prior_reach.h"

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "specula/acquire/bandwidth.h"
#include "specula/acquire/base_resample.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

void check_reach_options(const ReachOptions& o) {
  if (o.ladder.empty()) throw UsageError("confidence reach: the ladder of reaches is empty");
  for (std::size_t l = 0; l < o.ladder.size(); ++l)
    if (!(o.ladder[l] > 0 && o.ladder[l] <= 1) || (l > 0 && o.ladder[l] <= o.ladder[l - 1]))
      throw UsageError("confidence reach: the ladder must ascend strictly within (0, 1]");
  if (!(o.held_out > 0 && o.held_out < 1)) throw UsageError("confidence reach: held_out must be in (0, 1)");
}

// The samples of a source whose role is kept, in their order (the source outlives it).
class KeptSamples final : public SampleSource {
 public:
  KeptSamples(const SampleSource& src, std::span<const std::uint8_t> held) : src_(src) {
    for (std::size_t s = 0; s < held.size(); ++s)
      if (!held[s]) kept_.push_back(std::uint32_t(s));
  }
  std::size_t size() const override { return kept_.size(); }
  std::size_t bands() const override { return src_.bands(); }
  std::size_t block_rows() const override { return src_.block_rows(); }
  bool has_variance() const override { return src_.has_variance(); }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override {
    gather<double>(first, count, 4, out,
                   [&](std::size_t a, std::size_t n, std::span<double> to) { src_.read_angles(a, n, to); });
  }
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override {
    gather<float>(first, count, bands(), out,
                  [&](std::size_t a, std::size_t n, std::span<float> to) { src_.read_values(a, n, to); });
  }
  void read_variance(std::size_t first, std::size_t count, std::span<float> out) const override {
    gather<float>(first, count, bands(), out,
                  [&](std::size_t a, std::size_t n, std::span<float> to) { src_.read_variance(a, n, to); });
  }

 private:
  // Rows [first, first + count) of the kept samples, width values each, from the source's range that spans them.
  template <class T, class Read>
  void gather(std::size_t first, std::size_t count, std::size_t width, std::span<T> out, const Read& read) const {
    if (count == 0) return;
    if (first + count > kept_.size() || out.size() != count * width)
      throw UsageError("confidence reach: kept samples out of range");
    const std::size_t lo = kept_[first], hi = std::size_t(kept_[first + count - 1]) + 1;
    std::vector<T> buf((hi - lo) * width);
    read(lo, hi - lo, buf);
    for (std::size_t i = 0; i < count; ++i)
      std::copy_n(buf.begin() + std::ptrdiff_t((kept_[first + i] - lo) * width), width,
                  out.begin() + std::ptrdiff_t(i * width));
  }

  const SampleSource& src_;
  std::vector<std::uint32_t> kept_;
};

// Each sample's valid-cell position (or -1), its angles read in the source's blocks.
std::vector<std::int32_t> sample_slots(const SampleSource& src) {
  const std::size_t n = src.size(), block = std::max<std::size_t>(1, src.block_rows());
  std::vector<std::int32_t> slots(n);
  std::vector<double> angles;
  for (std::size_t first = 0; first < n; first += block) {
    check_interrupt();
    const std::size_t count = std::min(block, n - first);
    angles.resize(4 * count);
    src.read_angles(first, count, angles);
    valid_slots(angles, std::span(slots).subspan(first, count));
  }
  return slots;
}

// Per held-out cell of obs and ladder entry, its error (cells x ladder, row-major).
std::vector<double> held_out_errors(const PriorObservations& obs, std::span<const float> fitted,
                                    std::span<const float> kd, std::span<const float> gaps, std::size_t b,
                                    const ReachOptions& r, double max_gap, double eps) {
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  const std::size_t m = r.ladder.size();
  std::vector<double> err(obs.cell.size() * m, 0.0);
  parallel_for(
      obs.cell.size(),
      [&](std::size_t o) {
        const std::size_t cell = cells[obs.cell[o]];
        const double cc = cosines[obs.cell[o]];
        const bool local = kd[cell] >= 0;
        for (std::size_t l = 0; l < m; ++l) {
          const double c = local ? support_confidence(gaps[cell], max_gap, r.ladder[l]) : 0.0;
          double sum = 0;
          for (std::size_t k = 0; k < b; ++k) {
            const std::size_t at = k * brdf::kMerlCells + cell;
            const double blend = c * (local ? kd[at] : 0.0f) + (1 - c) * fitted[at];
            const double d = std::log((blend * cc + eps) / (double(obs.values[o * b + k]) * cc + eps));
            sum += d * d;
          }
          err[o * m + l] = sum / double(b);
        }
      },
      1024);
  return err;
}

// Per ladder entry the mean of err (cells x ladder) over the cells, summed in cell order.
std::vector<double> mean_errors(const std::vector<double>& err, std::size_t m) {
  std::vector<double> mean(m, 0.0);
  const std::size_t n = m ? err.size() / m : 0;
  for (std::size_t o = 0; o < n; ++o)
    for (std::size_t l = 0; l < m; ++l) mean[l] += err[o * m + l];
  for (double& x : mean) x = n ? x / double(n) : 0.0;
  return mean;
}

}  // namespace

ReachHoldout reach_holdout(const SampleSource& src, const ReachOptions& o) {
  check_reach_options(o);
  const std::vector<std::int32_t> slots = sample_slots(src);
  std::vector<std::uint32_t> count(valid_cells().size(), 0);
  for (const std::int32_t v : slots)
    if (v >= 0) ++count[std::size_t(v)];
  ReachHoldout h;
  std::vector<std::uint32_t> splittable;
  for (std::size_t i = 0; i < count.size(); ++i) {
    h.observed_cells += count[i] > 0;
    if (count[i] >= 2) splittable.push_back(std::uint32_t(i));
  }
  if (splittable.empty())
    throw InputError("confidence reach: no valid cell holds two samples, so none can lose half of them to validate on");
  const std::size_t want =
      std::clamp<std::size_t>(std::size_t(std::llround(o.held_out * double(splittable.size()))), 1, splittable.size());
  std::vector<std::uint8_t> chosen(count.size(), 0);
  for (const std::size_t j : select_indices(splittable.size(), want, o.seed)) chosen[splittable[j]] = 1;
  h.held_cells = want;
  h.held.assign(slots.size(), 0);
  std::vector<std::uint32_t> seen(count.size(), 0);
  for (std::size_t s = 0; s < slots.size(); ++s)
    if (slots[s] >= 0 && chosen[std::size_t(slots[s])] && seen[std::size_t(slots[s])]++ % 2 == 1) h.held[s] = 1;
  return h;
}

ReachChoice choose_confidence_reach(const SampleSource& src, const BrdfPrior& prior, const PriorResampleOptions& o,
                                    const ReachOptions& r) {
  return choose_confidence_reach(src, prior, memory_components(prior), o, r);
}

ReachChoice choose_confidence_reach(const SampleSource& src, const BrdfPrior& prior, const ComponentSource& components,
                                    const PriorResampleOptions& o, const ReachOptions& r) {
  check_reach_options(r);
  check_options(o.local);
  if (o.residuals) throw UsageError("confidence reach: chosen for the blend only, not the residuals form");
  if (src.bands() != prior.wavelengths.size())
    throw UsageError("prior: the samples have " + std::to_string(src.bands()) + " bands, the prior " +
                     std::to_string(prior.wavelengths.size()) + "; build the prior on the samples' bands");
  const auto t0 = std::chrono::steady_clock::now();
  ReachChoice out;
  out.holdout = reach_holdout(src, r);
  const std::vector<PriorObservations> parts =
      cell_means(src, o.fit.weights != PriorWeights::scatter, out.holdout.held, 2);
  const std::size_t b = src.bands();
  std::vector<float> fitted(b * brdf::kMerlCells, -1.0f);
  fit_prior(prior, components, parts[0], o.fit, fitted);
  const KeptSamples kept(src, out.holdout.held);
  std::vector<float> kd(b * brdf::kMerlCells), gaps(brdf::kMerlCells, -1.0f);
  resample_grid(SampleTree(kept, o.local.mapping), kept, o.local, kd, gaps);
  out.holdout.held = {};
  const std::size_t m = r.ladder.size();
  const std::vector<double> mean =
      mean_errors(held_out_errors(parts[1], fitted, kd, gaps, b, r, o.local.max_gap, prior.epsilon), m);
  std::size_t best = 0;
  for (std::size_t l = 0; l < m; ++l) {
    out.rows.push_back({.reach = r.ladder[l], .error = mean[l]});
    if (mean[l] < mean[best]) best = l;
  }
  out.reach = r.ladder[best];
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

nlohmann::ordered_json reach_choice_json(const ReachChoice& c, const ReachOptions& r) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const ReachRow& row : c.rows) rows.push_back({{"reach", row.reach}, {"error", row.error}});
  return {{"reach", c.reach},
          {"held_out", r.held_out},
          {"seed", r.seed},
          {"observed_cells", c.holdout.observed_cells},
          {"held_cells", c.holdout.held_cells},
          {"seconds", c.seconds},
          {"rows", rows}};
}

std::string reach_provenance(const ReachChoice& c, const ReachOptions& r) {
  return fmt::format("confidence_reach={} reach_auto=holdout held_out={} seed={}", c.reach, r.held_out, r.seed);
}

}  // namespace specula::acquire
