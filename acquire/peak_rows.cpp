#include "specula/acquire/peak_rows.h"

#include <numeric>
#include <string>
#include <vector>

#include "specula/acquire/phi_d_ring.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {

std::size_t settle_peak_rows(std::span<float> grid, std::size_t bands, const UnseenCap& cap, int rows) {
  if (grid.size() != bands * brdf::kMerlCells) throw UsageError("peak rows: a grid of bands x MERL cells needed");
  if (rows < 0 || rows >= brdf::kMerlThetaH)
    throw UsageError("peak rows: rows " + std::to_string(rows) + " must be in [0, " +
                     std::to_string(brdf::kMerlThetaH) + ")");
  const auto theta_h = [](int h) { return brdf::merl_cell_centre({.theta_h = h}).theta_h; };
  std::vector<std::size_t> settled(std::size_t(brdf::kMerlThetaD) * std::size_t(rows), 0);
  parallel_for(
      settled.size(),
      [&](std::size_t task) {
        const int d = int(task / std::size_t(rows)), h = int(task % std::size_t(rows));
        if (h < cap[std::size_t(d)]) return;
        const double keep = sin2_share(theta_h(h), theta_h(rows));
        const std::size_t first = brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = 0});
        settled[task] = settle_phi_d_rings(grid, bands, first, keep);
      },
      8);
  return std::accumulate(settled.begin(), settled.end(), std::size_t(0));
}

}  // namespace specula::acquire
