// The retro band's rise learned from its shoulder (acquire/retro_rise.h), on grids whose value is a material's level
// times a column's shape times exp(q[theta_d row]): the profile is q less q[width] (closed form); training grids whose
// band rows are an exact linear function of their shoulder rows teach a map that restores a held-out grid's band from
// its shoulder; only the band's rows from theta_h row 45 on change, each by one factor; adding the rows in overlapping
// blocks sums the same; sizes and widths are checked.
#include "specula/acquire/retro_rise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kBands = 2;
constexpr int kWidth = 5;

// A material's theta_d profile: a shoulder u x + v x^2 (x = (d - 5) / 10) from row 5 on, and below it, when banded,
// the band each test expects: 0.05 (5 - d) + 0.4 q[8] - 0.2 q[13] at row d; else flat at row 5's level.
std::vector<double> profile_of(double u, double v, bool banded) {
  std::vector<double> q(brdf::kMerlThetaD);
  for (int d = kWidth; d < brdf::kMerlThetaD; ++d) {
    const double x = (d - kWidth) / 10.0;
    q[std::size_t(d)] = u * x + v * x * x;
  }
  for (int d = 0; d < kWidth; ++d) q[std::size_t(d)] = banded ? 0.05 * (kWidth - d) + 0.4 * q[8] - 0.2 * q[13] : 0.0;
  return q;
}

// bands x kMerlCells: level_k (1 + 0.3 sin(theta_h + phi_d)) exp(q[theta_d]) at every valid cell, -1 elsewhere.
std::vector<float> grid_of(const std::vector<double>& q, double level) {
  std::vector<float> g(kBands * brdf::kMerlCells, -1.0f);
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell c = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(c)) continue;
    const double shape = (1 + 0.3 * std::sin(0.1 * c.theta_h + 0.05 * c.phi_d)) * std::exp(q[std::size_t(c.theta_d)]);
    for (std::size_t k = 0; k < kBands; ++k) g[k * brdf::kMerlCells + cell] = float(level * (1 + 0.5 * k) * shape);
  }
  return g;
}

TEST(RetroRise, ProfileIsTheRowsLevelsLessTheWidthsRow) {
  const std::vector<double> q = profile_of(0.3, -0.1, true);
  const std::vector<float> g = grid_of(q, 0.02);
  for (int w : {1, 5, 8}) {
    const std::vector<double> p = retro_profile(g, kBands, w);
    ASSERT_EQ(p.size(), std::size_t(3 * w));
    for (int r = 0; r < 3 * w; ++r) EXPECT_NEAR(p[std::size_t(r)], q[std::size_t(r)] - q[std::size_t(w)], 1e-5) << r;
  }
  std::vector<float> dark = g;  // a row without any light: no profile
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell)
    if (brdf::merl_cell(cell).theta_d == 3)
      for (std::size_t k = 0; k < kBands; ++k) dark[k * brdf::kMerlCells + cell] = 0.0f;
  EXPECT_TRUE(retro_profile(dark, kBands, kWidth).empty());
  EXPECT_THROW(retro_profile(g, kBands, 0), UsageError);
  EXPECT_THROW(retro_profile(g, kBands, 31), UsageError);
  EXPECT_THROW(retro_profile(std::span(g).first(10), kBands, kWidth), UsageError);
}

TEST(RetroRise, MapLearnedFromTrainingGridsRestoresAHeldOutBand) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.1, 0.6), v(-0.2, 0.2), level(0.01, 0.5);
  constexpr std::size_t kGrids = 16;
  RetroRiseTally whole(kGrids), pieces(kGrids);
  constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;
  for (std::size_t g = 0; g < kGrids; ++g) {
    const std::vector<float> grid = grid_of(profile_of(u(rng), v(rng), true), level(rng));
    whole.add(g, grid, kBands, 0, brdf::kMerlThetaH, 0, 1.5);
    // Blocks of rows [0, 50), [40, 70), [70, 90): the rows a block shares with the one before are skipped.
    std::size_t from = 0;
    for (const auto& [h0, rows] : {std::pair<std::size_t, std::size_t>{0, 50}, {40, 30}, {70, 20}}) {
      std::vector<float> block(kBands * rows * kRow);
      for (std::size_t k = 0; k < kBands; ++k)
        std::copy_n(grid.begin() + std::ptrdiff_t(k * brdf::kMerlCells + h0 * kRow), rows * kRow,
                    block.begin() + std::ptrdiff_t(k * rows * kRow));
      pieces.add(g, block, kBands, h0, rows, from, 1.5);
      from = h0 + rows;
    }
  }
  const std::vector<double> maps = whole.maps();
  ASSERT_EQ(maps.size(), retro_rise_size());
  EXPECT_EQ(pieces.maps(), maps);

  const std::vector<double> want = profile_of(0.45, 0.1, true);
  std::vector<float> grid = grid_of(profile_of(0.45, 0.1, false), 0.07);  // its band flat: no rise
  const std::vector<float> before = grid;
  const std::vector<double> factors = raise_retro_band(grid, kBands, maps, kWidth);
  ASSERT_EQ(factors.size(), std::size_t(kWidth));
  const std::vector<double> after = retro_profile(grid, kBands, kWidth);
  for (int r = 0; r < kWidth; ++r) {
    EXPECT_NEAR(after[std::size_t(r)], want[std::size_t(r)] - want[kWidth], 2e-3) << r;
    EXPECT_NEAR(std::log(factors[std::size_t(r)]), want[std::size_t(r)], 2e-3) << r;  // from flat at row 5's level
  }
  for (std::size_t k = 0; k < kBands; ++k)
    for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
      const brdf::MerlCell c = brdf::merl_cell(cell);
      const std::size_t at = k * brdf::kMerlCells + cell;
      if (c.theta_h < kRetroRiseFromThetaH || c.theta_d >= kWidth || !brdf::merl_cell_valid(c))
        ASSERT_EQ(grid[at], before[at]) << cell;
      else
        ASSERT_NEAR(grid[at], before[at] * factors[std::size_t(c.theta_d)], 1e-6 * before[at]) << cell;
    }
}

TEST(RetroRise, TableAndWidthsAreChecked) {
  const std::vector<double> maps(retro_rise_size(), 0.5);
  EXPECT_EQ(retro_rise_size(2), 10u);
  EXPECT_EQ(retro_rise_map(maps, 3).size(), 18u);
  EXPECT_EQ(retro_rise_map(maps, 3).data(), maps.data() + 10);
  EXPECT_TRUE(retro_rise_map(maps, kRetroLearnedRows + 1).empty());
  EXPECT_TRUE(retro_rise_map({}, 5).empty());
  const std::vector<double> odd(7, 0.0);
  EXPECT_THROW(retro_rise_map(odd, 1), UsageError);
  std::vector<float> grid = grid_of(profile_of(0.3, 0.0, true), 0.1);
  const std::vector<float> before = grid;
  EXPECT_TRUE(raise_retro_band(grid, kBands, maps, 0).empty());                      // no band
  EXPECT_TRUE(raise_retro_band(grid, kBands, maps, kRetroLearnedRows + 1).empty());  // no map that wide
  EXPECT_EQ(grid, before);
  EXPECT_THROW(raise_retro_band(grid, kBands, maps, -1), UsageError);
  RetroRiseTally tally(2);
  EXPECT_THROW(tally.add(2, grid, kBands, 0, brdf::kMerlThetaH, 0, 1.0), UsageError);
  EXPECT_THROW(tally.add(0, grid, kBands, 1, brdf::kMerlThetaH, 0, 1.0), UsageError);
}

}  // namespace
}  // namespace specula::acquire
