#include "specula/acquire/peak_rows.h"

#include <algorithm>
#include <numeric>
#include <string>
#include <vector>

#include "specula/acquire/phi_d_ring.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {

std::size_t settle_peak_rows(std::span<float> grid, std::size_t bands, const UnseenCap& cap,
                             std::span<const double> keep) {
  if (grid.size() != bands * brdf::kMerlCells) throw UsageError("peak rows: a grid of bands x MERL cells needed");
  if (keep.size() > std::size_t(brdf::kMerlThetaH))
    throw UsageError("peak rows: " + std::to_string(keep.size()) + " rows given, at most " +
                     std::to_string(brdf::kMerlThetaH));
  if (!std::ranges::all_of(keep, [](double k) { return k >= 0 && k <= 1; }))
    throw UsageError("peak rows: every row's keep must be in [0, 1]");
  const std::size_t rows = keep.size();
  std::vector<std::size_t> settled(std::size_t(brdf::kMerlThetaD) * rows, 0);
  parallel_for(
      settled.size(),
      [&](std::size_t task) {
        const int d = int(task / rows), h = int(task % rows);
        if (h < cap[std::size_t(d)] || keep[std::size_t(h)] >= 1) return;
        const std::size_t first = brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = 0});
        settled[task] = settle_phi_d_rings(grid, bands, first, keep[std::size_t(h)]);
      },
      8);
  return std::accumulate(settled.begin(), settled.end(), std::size_t(0));
}

std::vector<double> sin2_keeps(int rows) {
  if (rows < 0 || rows >= brdf::kMerlThetaH)
    throw UsageError("peak rows: rows " + std::to_string(rows) + " must be in [0, " +
                     std::to_string(brdf::kMerlThetaH) + ")");
  const auto theta_h = [](int h) { return brdf::merl_cell_centre({.theta_h = h}).theta_h; };
  std::vector<double> keep(static_cast<std::size_t>(rows));
  for (int h = 0; h < rows; ++h) keep[std::size_t(h)] = sin2_share(theta_h(h), theta_h(rows));
  return keep;
}

}  // namespace specula::acquire
