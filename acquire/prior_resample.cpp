#include "specula/acquire/prior_resample.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "specula/acquire/base_resample.h"
#include "specula/acquire/peak_cap.h"
#include "specula/acquire/retro_band.h"
#include "specula/acquire/retro_trend.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {
namespace {

// Position of each MERL cell in valid_cells() (-1 below the horizon).
const std::vector<std::int32_t>& valid_slot() {
  static const std::vector<std::int32_t> slot = [] {
    std::vector<std::int32_t> s(brdf::kMerlCells, -1);
    const auto& cells = valid_cells();
    for (std::size_t i = 0; i < cells.size(); ++i) s[cells[i]] = std::int32_t(i);
    return s;
  }();
  return slot;
}

// The observations' means, weights and spreads from their per-band sums (squares: of the values, or of the
// samples' own variances when obs.spread_is_noise) and counts.
void finish_means(std::span<const double> sums, std::span<const double> squares, std::span<const std::uint32_t> counts,
                  std::size_t b, PriorObservations& out) {
  out.values.resize(sums.size());
  out.spread.resize(sums.size());
  out.weight.resize(counts.size());
  for (std::size_t o = 0; o < counts.size(); ++o) {
    const double n = counts[o];
    out.weight[o] = float(n);
    for (std::size_t k = 0; k < b; ++k) {
      const double mean = sums[o * b + k] / n;
      out.values[o * b + k] = float(mean);
      out.spread[o * b + k] = out.spread_is_noise ? float(squares[o * b + k] / n)
                              : n > 1 ? float(std::max(0.0, (squares[o * b + k] - n * mean * mean) / (n - 1)))
                                      : 0.0f;
    }
  }
}

// The reach of MERL cell `cell`: its theta_h row's when given per row.
double reach_of(const PriorResampleOptions& o, std::size_t cell) {
  return o.reach_by_theta_h.empty() ? o.confidence_reach
                                    : o.reach_by_theta_h[std::size_t(brdf::merl_cell(cell).theta_h)];
}

// The band's weight of MERL cell `cell`: its theta_h row's when given per row.
double retro_weight_of(const PriorResampleOptions& o, std::size_t cell) {
  return o.retro_weight_by_theta_h.empty() ? *o.retro_weight
                                           : o.retro_weight_by_theta_h[std::size_t(brdf::merl_cell(cell).theta_h)];
}

// UsageError for options, sizes or bands resample_with_prior cannot take.
void check_prior_resample(const brdf::SampleSource& src, const BrdfPrior& prior, const PriorResampleOptions& o,
                          std::size_t grid_size, std::size_t confidence_size) {
  const std::size_t b = src.bands();
  if (b != prior.wavelengths.size())
    throw UsageError("prior: the samples have " + std::to_string(b) + " bands, the prior " +
                     std::to_string(prior.wavelengths.size()) + "; build the prior on the samples' bands");
  if (grid_size != b * brdf::kMerlCells || confidence_size != brdf::kMerlCells)
    throw UsageError("prior: grid or confidence of the wrong size");
  if (!(o.confidence_reach > 0 && o.confidence_reach <= 1))
    throw UsageError("prior: confidence_reach (the reach of the confidence, a fraction of max_gap) must be in (0, 1]");
  if (!o.reach_by_theta_h.empty() &&
      (o.reach_by_theta_h.size() != std::size_t(brdf::kMerlThetaH) ||
       !std::all_of(o.reach_by_theta_h.begin(), o.reach_by_theta_h.end(), [](double r) { return r > 0 && r <= 1; })))
    throw UsageError("prior: reach_by_theta_h needs one reach in (0, 1] per theta_h row (90)");
  if (o.cap_weight && !(*o.cap_weight >= 0 && *o.cap_weight <= 1))
    throw UsageError("prior: cap_weight (the kd-tree's weight in the unseen cap) must be in [0, 1]");
  if (o.retro_weight && !(*o.retro_weight >= 0 && *o.retro_weight <= 1))
    throw UsageError(
        "prior: retro_weight (the kd-tree's weight in the unseen retro-reflection band) must be in [0, 1]");
  if (!o.retro_weight_by_theta_h.empty() &&
      (!o.retro_weight || o.retro_weight_by_theta_h.size() != std::size_t(brdf::kMerlThetaH) ||
       !std::all_of(o.retro_weight_by_theta_h.begin(), o.retro_weight_by_theta_h.end(),
                    [](double w) { return w >= 0 && w <= 1; })))
    throw UsageError("prior: retro_weight_by_theta_h needs retro_weight and one weight in [0, 1] per theta_h row (90)");
  const double eps = o.blend_epsilon.value_or(prior.epsilon);
  if (o.log_blend && !(eps > 0 && std::isfinite(eps)))
    throw UsageError("prior: blend_epsilon (eps of the log blend) must be positive and finite");
}

}  // namespace

void valid_slots(std::span<const double> angles, std::span<std::int32_t> out, std::span<std::uint8_t> theta_d_rows) {
  if (angles.size() != 4 * out.size() || !(theta_d_rows.empty() || theta_d_rows.size() == out.size()))
    throw UsageError("prior: angles, slots and theta_d rows of different sizes");
  const auto& slot = valid_slot();
  const bool rows = !theta_d_rows.empty();
  parallel_for(
      out.size(),
      [&](std::size_t s) {
        const brdf::StdAngles a{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]};
        const bool ok = std::isfinite(a.theta_i) && std::isfinite(a.theta_o) && a.theta_i < std::numbers::pi / 2 &&
                        a.theta_o < std::numbers::pi / 2;
        const bool finite =
            std::isfinite(a.theta_i) && std::isfinite(a.phi_i) && std::isfinite(a.theta_o) && std::isfinite(a.phi_o);
        const brdf::MerlCell c = ok || (rows && finite) ? brdf::merl_cell(a) : brdf::MerlCell{};
        out[s] = ok ? slot[brdf::merl_index(c)] : -1;
        if (rows) theta_d_rows[s] = std::uint8_t(finite ? c.theta_d : brdf::kMerlThetaD);
      },
      4096);
}

std::vector<PriorObservations> cell_means(const brdf::SampleSource& src, bool use_variance,
                                          std::span<const std::uint8_t> part, std::size_t parts) {
  const std::size_t b = src.bands(), n = src.size(), block = src.block_rows();
  if (parts == 0 || !(part.empty() || part.size() == n))
    throw UsageError("prior: give at least one part and one part label per sample");
  struct Sums {
    std::vector<std::int32_t> obs_of;
    Buffer<double> sums, squares;  // reserved for every cell: growing by copies would fault in fresh pages each time
    std::vector<std::uint32_t> counts;
  };
  std::vector<Sums> acc(parts);
  std::vector<PriorObservations> out(parts);
  for (std::size_t q = 0; q < parts; ++q) {
    acc[q].obs_of.assign(valid_cells().size(), -1);
    acc[q].sums.reserve(std::min(valid_cells().size(), n) * b);
    acc[q].squares.reserve(std::min(valid_cells().size(), n) * b);
    out[q].spread_is_noise = use_variance && src.has_variance();
  }
  const bool noise = use_variance && src.has_variance();
  std::vector<double> angles;
  std::vector<float> values, variance;
  std::vector<std::int32_t> cell_of;
  Progress progress("cell means", n);
  for (std::size_t first = 0; first < n; first += block) {
    check_interrupt();
    const std::size_t count = std::min(block, n - first);
    angles.resize(count * 4);
    values.resize(count * b);
    cell_of.resize(count);
    src.read_angles(first, count, angles);
    src.read_values(first, count, values);
    if (noise) {
      variance.resize(count * b);
      src.read_variance(first, count, variance);
    }
    valid_slots(angles, cell_of);
    for (std::size_t s = 0; s < count; ++s) {  // in sample order: the sums do not depend on the thread count
      const std::int32_t v = cell_of[s];
      const std::size_t q = part.empty() ? 0 : part[first + s];
      if (v < 0 || q >= parts) continue;
      bool finite = true;
      for (std::size_t k = 0; k < b; ++k) finite &= std::isfinite(values[s * b + k]) && values[s * b + k] >= 0;
      if (!finite) continue;
      Sums& a = acc[q];
      if (a.obs_of[std::size_t(v)] < 0) {
        a.obs_of[std::size_t(v)] = std::int32_t(out[q].cell.size());
        out[q].cell.push_back(std::uint32_t(v));
        a.sums.resize(a.sums.size() + b, 0.0);
        a.squares.resize(a.squares.size() + b, 0.0);
        a.counts.push_back(0);
      }
      const std::size_t o = std::size_t(a.obs_of[std::size_t(v)]);
      for (std::size_t k = 0; k < b; ++k) {  // squares: the samples' variances when they carry them
        a.sums[o * b + k] += values[s * b + k];
        a.squares[o * b + k] += noise ? double(variance[s * b + k]) : double(values[s * b + k]) * values[s * b + k];
      }
      ++a.counts[o];
    }
    progress.advance(count);
  }
  for (std::size_t q = 0; q < parts; ++q) finish_means(acc[q].sums, acc[q].squares, acc[q].counts, b, out[q]);
  return out;
}

std::size_t bound_by_ceiling(const BrdfPrior& prior, std::span<const std::uint8_t> unseen, std::span<float> grid) {
  if (unseen.size() != brdf::kMerlCells || grid.empty() || grid.size() % brdf::kMerlCells != 0)
    throw UsageError("prior: the unseen flags or the grid are not of the MERL grid's cells");
  if (prior.ceiling.empty()) return 0;
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  if (prior.ceiling.size() != cells.size())
    throw UsageError("prior: malformed prior (its ceiling is not one per cell)");
  const std::size_t b = grid.size() / brdf::kMerlCells;
  std::vector<std::uint8_t> scaled(cells.size(), 0);
  parallel_for(
      cells.size(),
      [&](std::size_t i) {
        const std::size_t cell = cells[i];
        if (!unseen[cell]) return;
        float top = 0;
        for (std::size_t k = 0; k < b; ++k) top = std::max(top, grid[k * brdf::kMerlCells + cell]);
        const double limit = double(prior.ceiling[i]) / std::max(double(cosines[i]), 1e-6);
        if (!(top > limit)) return;
        const double scale = limit / top;
        for (std::size_t k = 0; k < b; ++k)
          grid[k * brdf::kMerlCells + cell] = float(grid[k * brdf::kMerlCells + cell] * scale);
        scaled[i] = 1;
      },
      4096);
  return std::size_t(std::ranges::count(scaled, std::uint8_t(1)));
}

double mix_estimates(double kd, double fit, double c, double cc, double eps, bool log) {
  if (c <= 0) return fit;
  if (!log || c >= 1) return c * kd + (1 - c) * fit;
  // never below 0: where kd or fit is 0, exp(...) - eps can round a hair under it
  return std::max(0.0, (std::exp(c * std::log(kd * cc + eps) + (1 - c) * std::log(fit * cc + eps)) - eps) / cc);
}

PriorObservations cell_means(const brdf::SampleSource& src, bool use_variance) {
  return std::move(cell_means(src, use_variance, {}, 1)[0]);
}

PriorResampleStats resample_with_prior(const brdf::SampleSource& src, const BrdfPrior& prior,
                                       const PriorResampleOptions& o, std::span<float> grid,
                                       std::span<float> confidence) {
  return resample_with_prior(src, prior, memory_components(prior), o, grid, confidence);
}

PriorResampleStats resample_with_prior(const brdf::SampleSource& src, const BrdfPrior& prior,
                                       const ComponentSource& components, const PriorResampleOptions& o,
                                       std::span<float> grid, std::span<float> confidence) {
  const std::size_t b = src.bands();
  check_prior_resample(src, prior, o, grid.size(), confidence.size());
  const double eps = o.blend_epsilon.value_or(prior.epsilon);
  PriorResampleStats st;
  const auto t0 = std::chrono::steady_clock::now();
  Buffer<float> fitted(b * brdf::kMerlCells, -1.0f);
  UnseenCap cap{};
  int retro_rows = 0;
  {  // the observations are freed before the kd-tree pass
    const PriorObservations obs = cell_means(src, o.fit.weights != PriorWeights::scatter);
    if (obs.cell.empty()) throw InputError("prior: no sample falls in a cell above the horizon");
    st.observed_cells = obs.cell.size();
    fit_prior(prior, components, obs, o.fit, fitted);
    cap = unseen_cap(obs);
    st.unseen_cap = cap;
    retro_rows = unseen_retro_rows(obs);
    st.unseen_retro_rows = retro_rows;
  }
  if (o.ceiling && !o.residuals) {
    std::vector<std::uint8_t> unseen(brdf::kMerlCells, 0);
    for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) unseen[cell] = in_unseen_cap(cap, cell);
    st.bounded_cells = bound_by_ceiling(prior, unseen, fitted);
  }
  if (o.energy_bound) st.energy_bounded_cells = bound_energy(fitted, b, *o.energy_bound);
  if (!o.retro_weight) retro_rows = 0;  // the band blends as elsewhere
  st.fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& cells = valid_cells();
  if (o.residuals) {
    std::copy(fitted.begin(), fitted.end(), grid.begin());
    st.local = resample_on_base(src, o.local, o.confidence_reach, base_from_grid(fitted, b), grid, confidence);
    st.filled_cells = cells.size();
    return st;
  }
  std::vector<float> gaps(brdf::kMerlCells, -1.0f);
  st.local = brdf::resample_grid(brdf::SampleTree(src, o.local.mapping), src, o.local, grid, gaps);
  if (retro_rows > 0 && o.retro_continued)
    continue_retro(grid, b, 0, retro_rows, retro_exponent(prior.retro_exponents, retro_rows), grid);
  std::fill(confidence.begin(), confidence.end(), -1.0f);
  const auto& cosines = valid_cell_cosines();
  parallel_for(
      cells.size(),
      [&](std::size_t i) {
        const std::size_t cell = cells[i];
        const bool local = grid[cell] >= 0;
        const bool in_cap = o.prior_in_cap && in_unseen_cap(cap, cell);
        const bool fixed = in_cap || in_unseen_retro(retro_rows, cell);
        const double c = !local   ? 0.0
                         : in_cap ? o.cap_weight.value_or(0.0)
                         : fixed  ? retro_weight_of(o, cell)
                                  : support_confidence(gaps[cell], o.local.max_gap, reach_of(o, cell));
        confidence[cell] = float(c);
        const bool log = fixed && o.log_blend;
        for (std::size_t k = 0; k < b; ++k) {
          const std::size_t at = k * brdf::kMerlCells + cell;
          grid[at] = float(mix_estimates(local ? grid[at] : 0.0f, fitted[at], c, cosines[i], eps, log));
        }
      },
      4096);
  st.filled_cells = cells.size();
  return st;
}

}  // namespace specula::acquire
