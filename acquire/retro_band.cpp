#include "specula/acquire/retro_band.h"

#include <algorithm>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

struct Line {
  double x_mean = 0, mean = 0, slope = 0;
  double at(double x) const { return mean + slope * (x - x_mean); }
};

// The least-squares line through (x[i], y[i]), its slope s shrunk to s max(0, 1 - se^2 / s^2) (se its standard error;
// more than 2 points): a trend lost in the noise stays flat.
Line shrunk_line(std::span<const double> x, std::span<const double> y) {
  const double n = double(y.size());
  Line l;
  for (std::size_t i = 0; i < y.size(); ++i) {
    l.x_mean += x[i] / n;
    l.mean += y[i] / n;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    sxy += (x[i] - l.x_mean) * y[i];
    sxx += (x[i] - l.x_mean) * (x[i] - l.x_mean);
  }
  l.slope = sxx > 0 ? sxy / sxx : 0.0;
  if (y.size() > 2 && l.slope != 0) {
    double rss = 0;
    for (std::size_t i = 0; i < y.size(); ++i) rss += std::pow(y[i] - l.at(x[i]), 2);
    l.slope *= std::max(0.0, 1.0 - rss / ((n - 2) * sxx) / (l.slope * l.slope));
  }
  return l;
}

// The abscissa of theta_d row r: its centre's theta_d squared (degrees^2). Reciprocity makes an isotropic BRDF even
// in theta_d at retro-reflection (f(theta_d, phi_d) = f(theta_d, phi_d + 180 degrees) about the pole theta_d = 0), so
// each column leaves row 0 with zero slope: ln f = a + b theta_d^2 near it.
double row_abscissa(int r) { return (r + 0.5) * (r + 0.5); }

}  // namespace

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
  double x[brdf::kMerlThetaD];  // count <= 45: end <= kMerlThetaD
  for (int r = known; r < std::min(end, brdf::kMerlThetaD); ++r) x[r - known] = row_abscissa(r);
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
          const Line l = shrunk_line({x, std::size_t(count)}, {y, std::size_t(count)});
          for (int r = first; r < known; ++r)
            if (brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = p}))
              out[k * brdf::kMerlCells + at(h, r, p)] = float(std::exp(l.at(row_abscissa(r))));
        }
      },
      256);
}

}  // namespace specula::acquire
