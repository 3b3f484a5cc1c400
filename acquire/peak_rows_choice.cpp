#include "specula/acquire/peak_rows_choice.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

#include "specula/acquire/peak_rows.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

// A sample in the peak's rows: its ring (theta_h row x kMerlThetaD + theta_d row), angles and ln of its band mean.
struct PeakSample {
  int ring = 0;
  double theta_h = 0, theta_d = 0, phi_d = 0, log_value = 0;
};

void check_options(const PeakRowsChoiceOptions& o) {
  if (o.group < 1 || o.group > kPeakRows)
    throw UsageError("peak rows: group " + std::to_string(o.group) + " must be in [1, " + std::to_string(kPeakRows) +
                     "]");
  if (!(o.theta_h_tolerance > 0) || !(o.theta_d_tolerance > 0))
    throw UsageError("peak rows: theta_h_tolerance and theta_d_tolerance must be positive");
  if (!(o.near > 0 && o.near < o.far && o.far < std::numbers::pi / 2))
    throw UsageError("peak rows: need 0 < near < far < pi / 2 (phi_d differences, radians)");
  if (o.ring_samples < 2) throw UsageError("peak rows: ring_samples must be at least 2");
}

// The samples in theta_h rows below kPeakRows whose band mean is finite and > 0, in sample order.
std::vector<PeakSample> peak_samples(const brdf::SampleSource& src) {
  const std::size_t b = src.bands(), n = src.size(), block = std::max<std::size_t>(1, src.block_rows());
  std::vector<PeakSample> out;
  std::vector<double> angles;
  std::vector<float> values;
  for (std::size_t first = 0; first < n; first += block) {
    check_interrupt();
    const std::size_t count = std::min(block, n - first);
    angles.resize(count * 4);
    values.resize(count * b);
    src.read_angles(first, count, angles);
    src.read_values(first, count, values);
    for (std::size_t s = 0; s < count; ++s) {
      const brdf::StdAngles a{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]};
      if (!(a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2 && std::isfinite(a.phi_i) &&
            std::isfinite(a.phi_o)))
        continue;
      const brdf::HalfDiff h = brdf::half_diff(a);
      const brdf::MerlCell c = brdf::merl_cell(h);
      if (c.theta_h >= kPeakRows) continue;
      double mean = 0;
      for (std::size_t k = 0; k < b; ++k) mean += values[s * b + k];
      mean /= double(b);
      if (!(mean > 0 && std::isfinite(mean))) continue;
      out.push_back({.ring = c.theta_h * brdf::kMerlThetaD + c.theta_d,
                     .theta_h = h.theta_h,
                     .theta_d = h.theta_d,
                     .phi_d = std::fmod(h.phi_d + 2 * std::numbers::pi, std::numbers::pi),
                     .log_value = std::log(mean)});
    }
  }
  return out;
}

// Sums of squared ln differences and counts of a ring's near and far pairs of samples, and of its far pairs of cells.
struct PairSums {
  double near = 0, far = 0, grid = 0;
  std::size_t near_pairs = 0, far_pairs = 0, grid_pairs = 0;
};

// The grid's far pairs on the ring of theta_h row h and theta_d row d into p: ln of each cell's band mean, cells > 0.
void grid_pairs(std::span<const float> grid, std::size_t bands, int h, int d, const PeakRowsChoiceOptions& o,
                PairSums& p) {
  const std::size_t first = brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = 0});
  std::vector<double> ln(brdf::kMerlPhiD, std::nan(""));
  for (std::size_t f = 0; f < ln.size(); ++f) {
    double mean = 0;
    for (std::size_t k = 0; k < bands; ++k) mean += grid[k * brdf::kMerlCells + first + f];
    if (mean > 0) ln[f] = std::log(mean / double(bands));
  }
  const double step = std::numbers::pi / brdf::kMerlPhiD;
  for (std::size_t i = 0; i < ln.size(); ++i)
    for (std::size_t j = i + 1; j < ln.size(); ++j) {
      const double dp = std::min(double(j - i), double(ln.size() - (j - i))) * step;
      if (dp <= o.far || std::isnan(ln[i]) || std::isnan(ln[j])) continue;
      p.grid += (ln[i] - ln[j]) * (ln[i] - ln[j]);
      ++p.grid_pairs;
    }
}

PairSums ring_pairs(std::span<const PeakSample> ring, const PeakRowsChoiceOptions& o) {
  const std::size_t step = (ring.size() + o.ring_samples - 1) / o.ring_samples;
  PairSums p;
  for (std::size_t i = 0; i < ring.size(); i += step)
    for (std::size_t j = i + step; j < ring.size(); j += step) {
      const PeakSample &a = ring[i], &b = ring[j];
      if (std::abs(a.theta_h - b.theta_h) > o.theta_h_tolerance * std::max(a.theta_h, b.theta_h) ||
          std::abs(a.theta_d - b.theta_d) > o.theta_d_tolerance)
        continue;
      double dp = std::abs(a.phi_d - b.phi_d);
      dp = std::min(dp, std::numbers::pi - dp);
      const double d2 = (a.log_value - b.log_value) * (a.log_value - b.log_value);
      if (dp < o.near) {
        p.near += d2;
        ++p.near_pairs;
      } else if (dp > o.far) {
        p.far += d2;
        ++p.far_pairs;
      }
    }
  return p;
}

}  // namespace

PeakRowsChoice choose_peak_rows(const brdf::SampleSource& src, std::span<const float> grid, std::size_t bands,
                                const PeakRowsChoiceOptions& o) {
  check_options(o);
  if (grid.size() != bands * brdf::kMerlCells || bands == 0)
    throw UsageError("peak rows: a grid of bands x MERL cells needed");
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<PeakSample> samples = peak_samples(src);
  std::stable_sort(samples.begin(), samples.end(),
                   [](const PeakSample& a, const PeakSample& b) { return a.ring < b.ring; });
  std::vector<std::size_t> start;  // each ring's first sample; a last entry closes the last ring
  for (std::size_t s = 0; s < samples.size(); ++s)
    if (s == 0 || samples[s].ring != samples[s - 1].ring) start.push_back(s);
  start.push_back(samples.size());
  std::vector<PairSums> rings(start.size() - 1);
  parallel_for(
      rings.size(),
      [&](std::size_t r) {
        const std::span<const PeakSample> ring = std::span(samples).subspan(start[r], start[r + 1] - start[r]);
        rings[r] = ring_pairs(ring, o);
        if (ring.size() >= 2)
          grid_pairs(grid, bands, ring[0].ring / brdf::kMerlThetaD, ring[0].ring % brdf::kMerlThetaD, o, rings[r]);
      },
      1);
  PeakRowsChoice c{.samples = samples.size()};
  std::vector<PairSums> groups(std::size_t((kPeakRows + o.group - 1) / o.group));
  for (std::size_t r = 0; r < rings.size(); ++r) {  // in ring order: the sums do not depend on the thread count
    PairSums& g = groups[std::size_t(samples[start[r]].ring / brdf::kMerlThetaD / o.group)];
    g.near += rings[r].near;
    g.far += rings[r].far;
    g.near_pairs += rings[r].near_pairs;
    g.far_pairs += rings[r].far_pairs;
    g.grid += rings[r].grid;
    g.grid_pairs += rings[r].grid_pairs;
  }
  bool started = false, ended = false;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const PairSums& p = groups[g];
    PeakRowsGroup out{.first_row = int(g) * o.group, .near_pairs = p.near_pairs, .far_pairs = p.far_pairs};
    out.measured = p.near_pairs >= o.min_pairs && p.far_pairs >= o.min_pairs;
    if (p.near_pairs > 0) out.near_rms = std::sqrt(p.near / double(p.near_pairs));
    if (p.far_pairs > 0) out.far_rms = std::sqrt(p.far / double(p.far_pairs));
    if (out.measured) out.spread = std::sqrt(std::max(0.0, out.far_rms * out.far_rms - out.near_rms * out.near_rms));
    if (p.grid_pairs > 0) out.grid_spread = std::sqrt(p.grid / double(p.grid_pairs));
    if (out.measured && out.grid_spread > 0) out.keep = std::min(1.0, std::pow(out.spread / out.grid_spread, 2));
    c.groups.push_back(out);
    if (ended || (!started && !out.measured)) continue;
    started = true;
    if (out.measured && out.grid_spread > out.spread)
      c.rows = std::min(kPeakRows, out.first_row + o.group);
    else
      ended = true;
  }
  const auto first = std::ranges::find_if(c.groups, [](const PeakRowsGroup& g) { return g.measured; });
  for (auto g = c.groups.begin(); g != first; ++g) g->keep = first == c.groups.end() ? 1.0 : first->keep;
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return c;
}

std::vector<double> row_keeps(const PeakRowsChoice& c) {
  std::vector<double> keep(kPeakRows, 1.0);
  for (const PeakRowsGroup& g : c.groups)
    std::fill(keep.begin() + std::clamp(g.first_row, 0, kPeakRows), keep.end(), g.keep);
  return keep;
}

nlohmann::ordered_json peak_rows_choice_json(const PeakRowsChoice& c) {
  nlohmann::ordered_json groups = nlohmann::ordered_json::array();
  for (const PeakRowsGroup& g : c.groups)
    groups.push_back({{"first_row", g.first_row},
                      {"near_pairs", g.near_pairs},
                      {"far_pairs", g.far_pairs},
                      {"near_rms", g.near_rms},
                      {"far_rms", g.far_rms},
                      {"spread", g.spread},
                      {"grid_spread", g.grid_spread},
                      {"measured", g.measured},
                      {"keep", g.keep}});
  return {{"rows", c.rows}, {"samples", c.samples}, {"seconds", c.seconds}, {"groups", groups}};
}

}  // namespace specula::acquire
