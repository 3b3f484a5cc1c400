#include "specula/acquire/retro_rise.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/store/prior.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;  // cells per theta_h row
constexpr int kMaxWidth = brdf::kMerlThetaD / 3;

// Where width w's rows start in a grid's sums of widths 1 .. w - 1 (3 rows each per unit of width).
constexpr std::size_t sums_offset(int w) { return std::size_t(3 * (w - 1) * w / 2); }

// Adds to sums (3w values) the profile sums of width w over theta_h rows [from, h0 + rows) of values (bands x rows x
// kRow, rows from h0), each value times scale; the same sums for any thread count.
void add_sums(std::span<const float> values, std::size_t bands, std::size_t h0, std::size_t rows, std::size_t from,
              double scale, int w, std::span<double> sums) {
  const std::size_t first = std::max({h0, from, std::size_t(kRetroRiseFromThetaH)});
  if (first >= h0 + rows) return;
  const std::size_t n = h0 + rows - first, depth = std::size_t(3 * w);
  std::vector<double> part(n * depth, 0.0);
  parallel_for(n, [&](std::size_t i) {
    const int h = int(first + i);
    const std::size_t at = (first - h0 + i) * kRow;
    for (int p = 0; p < brdf::kMerlPhiD; ++p) {
      bool valid = true;
      for (int r = 0; valid && r < int(depth); ++r)
        valid = brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = p});
      if (!valid) continue;
      for (std::size_t r = 0; r < depth; ++r)
        for (std::size_t k = 0; k < bands; ++k) {
          const float v = values[k * rows * kRow + at + r * brdf::kMerlPhiD + std::size_t(p)];
          part[i * depth + r] += std::isfinite(v) ? std::max(double(v), 0.0) * scale : 0.0;
        }
    }
  });
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t r = 0; r < depth; ++r) sums[r] += part[i * depth + r];
}

// The profile of sums (3w rows): ln of each less that of row w; empty when one is not > 0.
std::vector<double> profile_of(std::span<const double> sums, int w) {
  if (!std::ranges::all_of(sums, [](double s) { return s > 0 && std::isfinite(s); })) return {};
  std::vector<double> p(sums.size());
  for (std::size_t r = 0; r < sums.size(); ++r) p[r] = std::log(sums[r] / sums[std::size_t(w)]);
  return p;
}

// Width w's map applied to profile p: the predicted rows 0 .. w - 1.
std::vector<double> predicted(std::span<const double> map, std::span<const double> p, int w) {
  std::vector<double> out(std::size_t(w), 0.0);
  for (int j = 0; j < w; ++j) {
    double y = map[std::size_t(j)];
    for (int q = 1; q < 2 * w; ++q) y += map[std::size_t(q * w + j)] * p[std::size_t(w + q)];
    out[std::size_t(j)] = y;
  }
  return out;
}

}  // namespace

std::size_t retro_rise_size(int widths) { return store::retro_rise_values(std::size_t(std::max(widths, 0))); }

std::span<const double> retro_rise_map(std::span<const double> maps, int width) {
  int widths = 0;
  while (retro_rise_size(widths) < maps.size()) ++widths;
  if (retro_rise_size(widths) != maps.size())
    throw UsageError("retro rise: a table of " + std::to_string(maps.size()) +
                     " values holds no whole number of maps (2 w^2 values for width w = 1, 2, ...)");
  if (width < 1 || width > widths) return {};
  return maps.subspan(retro_rise_size(width - 1), std::size_t(2 * width * width));
}

std::vector<double> retro_profile(std::span<const float> grid, std::size_t bands, int width) {
  if (grid.size() != bands * brdf::kMerlCells || bands == 0)
    throw UsageError("retro rise: a grid of bands x MERL cells needed");
  if (width < 1 || width > kMaxWidth)
    throw UsageError("retro rise: width " + std::to_string(width) + " must be in [1, " + std::to_string(kMaxWidth) +
                     "]");
  std::vector<double> sums(std::size_t(3 * width), 0.0);
  add_sums(grid, bands, 0, brdf::kMerlThetaH, 0, 1.0, width, sums);
  return profile_of(sums, width);
}

RetroRiseTally::RetroRiseTally(std::size_t grids)
    : grids_(grids), sums_(grids * sums_offset(kRetroLearnedRows + 1), 0.0) {}

void RetroRiseTally::add(std::size_t g, std::span<const float> values, std::size_t bands, std::size_t h0,
                         std::size_t rows, std::size_t from, double scale) {
  if (g >= grids_ || bands == 0 || values.size() != bands * rows * kRow || h0 + rows > std::size_t(brdf::kMerlThetaH))
    throw UsageError("retro rise: rows of bands x theta_h rows x MERL theta_d x phi_d values of a tallied grid needed");
  const std::size_t per_grid = sums_offset(kRetroLearnedRows + 1);
  for (int w = 1; w <= kRetroLearnedRows; ++w)
    add_sums(values, bands, h0, rows, from, scale, w,
             std::span(sums_).subspan(g * per_grid + sums_offset(w), std::size_t(3 * w)));
}

std::vector<double> RetroRiseTally::maps() const {
  std::vector<double> out;
  out.reserve(retro_rise_size());
  const std::size_t per_grid = sums_offset(kRetroLearnedRows + 1);
  for (int w = 1; w <= kRetroLearnedRows; ++w) {
    std::vector<std::vector<double>> profiles;
    for (std::size_t g = 0; g < grids_; ++g) {
      auto p = profile_of(std::span(sums_).subspan(g * per_grid + sums_offset(w), std::size_t(3 * w)), w);
      if (!p.empty()) profiles.push_back(std::move(p));
    }
    const Eigen::Index n = Eigen::Index(profiles.size()), cols = 2 * w;
    Eigen::MatrixXd x(n, cols), y(n, w);
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto& p = profiles[std::size_t(i)];
      x(i, 0) = 1;
      for (int q = 1; q < cols; ++q) x(i, q) = p[std::size_t(w + q)];
      for (int j = 0; j < w; ++j) y(i, j) = p[std::size_t(j)];
    }
    const Eigen::MatrixXd a = x.transpose() * x + kRetroRiseLambda * Eigen::MatrixXd::Identity(cols, cols);
    const Eigen::MatrixXd m = a.ldlt().solve(x.transpose() * y);  // 2w x w
    for (Eigen::Index q = 0; q < cols; ++q)
      for (Eigen::Index j = 0; j < w; ++j) out.push_back(m(q, j));
  }
  return out;
}

std::vector<double> raise_retro_band(std::span<float> grid, std::size_t bands, std::span<const double> maps, int rows) {
  if (rows < 0) throw UsageError("retro rise: rows must be >= 0");
  const std::span<const double> map = retro_rise_map(maps, rows);
  if (rows == 0 || map.empty()) return {};
  const std::vector<double> p = retro_profile(grid, bands, rows);
  if (p.empty()) return {};
  const std::vector<double> want = predicted(map, p, rows);
  std::vector<double> factors(static_cast<std::size_t>(rows));
  for (int r = 0; r < rows; ++r) factors[std::size_t(r)] = std::exp(want[std::size_t(r)] - p[std::size_t(r)]);
  parallel_for(std::size_t(brdf::kMerlThetaH - kRetroRiseFromThetaH), [&](std::size_t i) {
    const int h = kRetroRiseFromThetaH + int(i);
    for (int r = 0; r < rows; ++r)
      for (int q = 0; q < brdf::kMerlPhiD; ++q) {
        if (!brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = q})) continue;
        const std::size_t cell = brdf::merl_index({.theta_h = h, .theta_d = r, .phi_d = q});
        for (std::size_t k = 0; k < bands; ++k) grid[k * brdf::kMerlCells + cell] *= float(factors[std::size_t(r)]);
      }
  });
  return factors;
}

}  // namespace specula::acquire
