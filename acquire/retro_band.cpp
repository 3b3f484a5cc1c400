#include "specula/acquire/retro_band.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include "specula/acquire/phi_d_ring.h"
#include "specula/acquire/retro_trend.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {

int unseen_retro_rows(std::span<const std::uint32_t> observed) {
  int rows = brdf::kMerlThetaD;
  const auto& cells = valid_cells();
  for (const std::uint32_t v : observed) rows = std::min(rows, brdf::merl_cell(std::size_t(cells[v])).theta_d);
  return rows;
}

bool in_unseen_retro(int rows, std::size_t cell) { return brdf::merl_cell(cell).theta_d < rows; }

void continue_retro(std::span<const float> grid, std::size_t bands, int first, int count, double exponent,
                    std::span<float> out) {
  if (grid.size() != bands * brdf::kMerlCells || out.size() != grid.size())
    throw UsageError("retro band: grids of bands x MERL cells needed");
  if (first < 0 || count < 1) throw UsageError("retro band: rows to continue must be a positive count from row 0 up");
  if (!(exponent > 0) || !std::isfinite(exponent)) throw UsageError("retro band: the exponent must be positive");
  const int known = first + count, end = first + 2 * count;
  double x[brdf::kMerlThetaD];  // count <= 45: end <= kMerlThetaD
  for (int r = known; r < std::min(end, brdf::kMerlThetaD); ++r) x[r - known] = retro_abscissa(r, exponent);
  const auto at = [](int h, int d, int p) { return brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = p}); };
  parallel_for(
      std::size_t(brdf::kMerlThetaH) * brdf::kMerlPhiD,
      [&](std::size_t column) {
        const int h = int(column / brdf::kMerlPhiD), p = int(column % brdf::kMerlPhiD);
        bool ok = end <= brdf::kMerlThetaD;
        for (int r = known; ok && r < end; ++r)
          for (std::size_t k = 0; ok && k < bands; ++k) ok = grid[k * brdf::kMerlCells + at(h, r, p)] > 0;
        if (!ok) return;
        double y[brdf::kMerlThetaD];
        for (std::size_t k = 0; k < bands; ++k) {
          for (int r = known; r < end; ++r) y[r - known] = std::log(double(grid[k * brdf::kMerlCells + at(h, r, p)]));
          const TrendLine l = shrunk_line({x, std::size_t(count)}, {y, std::size_t(count)});
          for (int r = first; r < known; ++r)
            if (brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = p}))
              out[k * brdf::kMerlCells + at(h, r, p)] = float(std::exp(l.at(retro_abscissa(r, exponent))));
        }
      },
      256);
}

std::size_t settle_retro_pole(std::span<float> grid, std::size_t bands, int rows) {
  if (grid.size() != bands * brdf::kMerlCells) throw UsageError("retro pole: a grid of bands x MERL cells needed");
  if (rows < 0 || rows >= brdf::kMerlThetaD)
    throw UsageError("retro pole: rows " + std::to_string(rows) + " must be in [0, " +
                     std::to_string(brdf::kMerlThetaD) + ")");
  const auto radians = [](int r) { return retro_row_centre(r) * std::numbers::pi / 180; };
  std::vector<std::size_t> settled(std::size_t(brdf::kMerlThetaH) * std::size_t(rows), 0);
  parallel_for(
      settled.size(),
      [&](std::size_t task) {
        const int h = int(task / std::size_t(rows)), r = int(task % std::size_t(rows));
        const double keep = sin2_share(radians(r), radians(rows));
        const std::size_t first = brdf::merl_index({.theta_h = h, .theta_d = r, .phi_d = 0});
        settled[task] = settle_phi_d_rings(grid, bands, first, keep);
      },
      8);
  return std::accumulate(settled.begin(), settled.end(), std::size_t(0));
}

}  // namespace specula::acquire
