#include "specula/acquire/energy_bound.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::size_t kSplit = 2;  // sub-rows per theta_h row of the grid
constexpr std::size_t kPhiH = 360;
constexpr double kMedianBelowDeg = 60;

// Per incidence row the MERL cells its albedo integral reads and the projected solid angle each stands for.
struct AlbedoTable {
  std::vector<std::size_t> start;  // kAlbedoRows + 1 offsets into cell and weight
  std::vector<std::uint32_t> cell;
  std::vector<double> weight;
};

// One row's (cell, weight) pairs, summed per cell in cell order.
std::vector<std::pair<std::uint32_t, double>> row_weights(std::size_t r) {
  const double ti = (double(r) + 0.5) * kPi / 180;
  const Eigen::Vector3d wi(std::sin(ti), 0, std::cos(ti));
  const std::size_t nu = kSplit * std::size_t(brdf::kMerlThetaH);
  std::vector<std::pair<std::uint32_t, double>> pairs;
  for (std::size_t iu = 0; iu < nu; ++iu) {
    const double u = (double(iu) + 0.5) / double(nu), th = u * u * kPi / 2;
    const double dwh = std::sin(th) * (kPi * u / double(nu)) * (2 * kPi / double(kPhiH));  // sin th d th d phi
    for (std::size_t ip = 0; ip < kPhiH; ++ip) {
      const double ph = (double(ip) + 0.5) * 2 * kPi / double(kPhiH);
      const Eigen::Vector3d h = brdf::direction(th, ph);
      const double c = h.dot(wi);
      const Eigen::Vector3d wo = 2 * c * h - wi;
      if (c <= 0 || wo.z() <= 0) continue;
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::half_diff(wi, wo)));
      pairs.emplace_back(std::uint32_t(cell), wo.z() * 4 * c * dwh);  // d wo = 4 (wi . h) d wh
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::size_t n = 0;
  for (const auto& p : pairs) {
    if (n > 0 && pairs[n - 1].first == p.first)
      pairs[n - 1].second += p.second;
    else
      pairs[n++] = p;
  }
  pairs.resize(n);
  return pairs;
}

const AlbedoTable& albedo_table() {
  static const AlbedoTable table = [] {
    std::vector<std::vector<std::pair<std::uint32_t, double>>> rows(kAlbedoRows);
    parallel_for(kAlbedoRows, [&](std::size_t r) { rows[r] = row_weights(r); });
    AlbedoTable t;
    t.start.push_back(0);
    for (const auto& row : rows) {
      for (const auto& [cell, w] : row) {
        t.cell.push_back(cell);
        t.weight.push_back(w);
      }
      t.start.push_back(t.cell.size());
    }
    return t;
  }();
  return table;
}

// The largest band of a cell's spectrum.
double largest_band(std::span<const float> grid, std::size_t bands, std::size_t cell) {
  double v = 0;
  for (std::size_t k = 0; k < bands; ++k) v = std::max(v, double(grid[k * brdf::kMerlCells + cell]));
  return v;
}

// The albedo of row r per band.
void row_albedo(const AlbedoTable& t, std::size_t r, std::span<const float> grid, std::size_t bands,
                std::span<double> out) {
  std::fill(out.begin(), out.end(), 0.0);
  for (std::size_t j = t.start[r]; j < t.start[r + 1]; ++j) {
    const std::size_t cell = t.cell[j];
    if (!(grid[cell] >= 0)) continue;
    for (std::size_t k = 0; k < bands; ++k)
      out[k] += t.weight[j] * std::max(0.0, double(grid[k * brdf::kMerlCells + cell]));
  }
}

// The threshold that brings row r within limit (per band) when the cells above it are cut to it: the albedo is
// linear in the threshold t between two cells' largest bands, A + t B (A from the cells below t, B the rest's
// albedo per unit of their largest band), so the segments are walked down from the brightest cell.
double row_threshold(const AlbedoTable& t, std::size_t r, std::span<const float> grid, std::size_t bands,
                     std::span<const double> limit) {
  std::vector<std::pair<double, std::size_t>> bright;  // (largest band, table entry)
  for (std::size_t j = t.start[r]; j < t.start[r + 1]; ++j)
    if (grid[t.cell[j]] >= 0) {
      const double v = largest_band(grid, bands, t.cell[j]);
      if (v > 0) bright.emplace_back(v, j);
    }
  std::sort(bright.begin(), bright.end());
  std::vector<double> below(bands, 0.0), above(bands, 0.0);
  auto add = [&](std::size_t i, double sign_below) {
    const auto [v, j] = bright[i];
    for (std::size_t k = 0; k < bands; ++k) {
      const double wf = t.weight[j] * std::max(0.0, double(grid[k * brdf::kMerlCells + t.cell[j]]));
      below[k] += sign_below * wf;
      if (sign_below < 0) above[k] += wf / v;
    }
  };
  for (std::size_t i = 0; i < bright.size(); ++i) add(i, 1);
  for (std::size_t i = bright.size(); i-- > 0;) {
    add(i, -1);  // bright[i..] are cut: t in [bright[i - 1].v, bright[i].v]
    double top = INFINITY;
    for (std::size_t k = 0; k < bands; ++k)
      if (above[k] > 0) top = std::min(top, std::max(0.0, limit[k] - below[k]) / above[k]);
    const double floor = i > 0 ? bright[i - 1].first : 0.0;
    if (top >= floor) return std::min(top, bright[i].first);
  }
  return 0;
}

void check_grid(std::size_t grid_size, std::size_t bands) {
  if (bands == 0 || grid_size != bands * brdf::kMerlCells)
    throw UsageError("energy bound: the grid is not bands x 90 x 90 x 180 values");
}

}  // namespace

void directional_albedo(std::span<const float> grid, std::size_t bands, std::span<double> out) {
  check_grid(grid.size(), bands);
  if (out.size() != kAlbedoRows * bands) throw UsageError("energy bound: the albedo needs rows x bands values");
  const AlbedoTable& t = albedo_table();
  parallel_for(kAlbedoRows, [&](std::size_t r) { row_albedo(t, r, grid, bands, out.subspan(r * bands, bands)); });
}

std::size_t bound_energy(std::span<float> grid, std::size_t bands, const EnergyBoundOptions& o) {
  check_grid(grid.size(), bands);
  if (!(o.kappa > 0 && std::isfinite(o.kappa) && o.floor > 0 && std::isfinite(o.floor)))
    throw UsageError(
        "energy bound: floor (the least albedo bound) and kappa (the bound's multiple of the material's "
        "median albedo) must be positive");
  std::vector<double> rho(kAlbedoRows * bands);
  directional_albedo(grid, bands, rho);
  std::vector<double> limit(bands);
  const std::size_t below = std::size_t(kMedianBelowDeg);
  for (std::size_t k = 0; k < bands; ++k) {
    std::vector<double> column(below);
    for (std::size_t r = 0; r < below; ++r) column[r] = rho[r * bands + k];
    std::nth_element(column.begin(), column.begin() + below / 2, column.end());
    limit[k] = std::max(o.floor, o.kappa * column[below / 2]);
  }
  const AlbedoTable& t = albedo_table();
  std::vector<double> threshold(kAlbedoRows, INFINITY);
  parallel_for(kAlbedoRows, [&](std::size_t r) {
    bool over = false;
    for (std::size_t k = 0; k < bands; ++k) over |= rho[r * bands + k] > limit[k];
    if (over) threshold[r] = row_threshold(t, r, grid, bands, limit);
  });
  std::vector<double> factor(brdf::kMerlCells, 1.0);
  for (std::size_t r = 0; r < kAlbedoRows; ++r) {
    if (!std::isfinite(threshold[r])) continue;
    for (std::size_t j = t.start[r]; j < t.start[r + 1]; ++j) {
      const std::size_t cell = t.cell[j];
      if (!(grid[cell] >= 0)) continue;
      const double v = largest_band(grid, bands, cell);
      if (v > threshold[r]) factor[cell] = std::min(factor[cell], threshold[r] / v);
    }
  }
  std::size_t scaled = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    if (factor[cell] >= 1) continue;
    ++scaled;
    for (std::size_t k = 0; k < bands; ++k)
      grid[k * brdf::kMerlCells + cell] = float(grid[k * brdf::kMerlCells + cell] * factor[cell]);
  }
  return scaled;
}

}  // namespace specula::acquire
