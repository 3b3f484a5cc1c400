#include "specula/acquire/retro_band.h"

#include <algorithm>
#include <cmath>

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

void continue_retro(std::span<const float> grid, std::size_t bands, int first, int count, std::span<float> out) {
  if (grid.size() != bands * brdf::kMerlCells || out.size() != grid.size())
    throw UsageError("retro band: grids of bands x MERL cells needed");
  if (first < 0 || count < 1) throw UsageError("retro band: rows to continue must be a positive count from row 0 up");
  const int known = first + count, end = first + 2 * count;
  const double mid = known + (count - 1) / 2.0;
  double sxx = 0;
  for (int r = known; r < end; ++r) sxx += (r - mid) * (r - mid);
  const auto at = [](int h, int d, int p) { return brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = p}); };
  parallel_for(
      std::size_t(brdf::kMerlThetaH) * brdf::kMerlPhiD,
      [&](std::size_t column) {
        const int h = int(column / brdf::kMerlPhiD), p = int(column % brdf::kMerlPhiD);
        bool ok = end <= brdf::kMerlThetaD;
        for (int r = known; ok && r < end; ++r)
          for (std::size_t k = 0; ok && k < bands; ++k) ok = grid[k * brdf::kMerlCells + at(h, r, p)] > 0;
        if (!ok) return;
        for (std::size_t k = 0; k < bands; ++k) {
          double sum = 0, sxy = 0;
          for (int r = known; r < end; ++r) {
            const double y = std::log(double(grid[k * brdf::kMerlCells + at(h, r, p)]));
            sum += y;
            sxy += (r - mid) * y;
          }
          const double mean = sum / count;
          double slope = count > 1 ? sxy / sxx : 0.0;
          if (count > 2 && slope != 0) {  // shrunk by its squared standard error: a trend lost in noise stays flat
            double rss = 0;
            for (int r = known; r < end; ++r) {
              const double e = std::log(double(grid[k * brdf::kMerlCells + at(h, r, p)])) - mean - slope * (r - mid);
              rss += e * e;
            }
            slope *= std::max(0.0, 1.0 - rss / ((count - 2) * sxx) / (slope * slope));
          }
          for (int r = first; r < known; ++r)
            if (brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = p}))
              out[k * brdf::kMerlCells + at(h, r, p)] = float(std::exp(mean + slope * (r - mid)));
        }
      },
      256);
}

}  // namespace specula::acquire
