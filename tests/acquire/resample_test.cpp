#include "acquire/resample.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

brdf::StdAngles random_angles(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  return {t(rng), p(rng), t(rng), p(rng)};
}

TEST(Mapping, IsotropyAndReciprocity) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 200; ++i) {
    const brdf::StdAngles a = random_angles(rng);
    const double turn = 0.37 * i;
    const brdf::StdAngles rotated{a.theta_i, a.phi_i + turn, a.theta_o, a.phi_o + turn};
    const brdf::StdAngles mirrored{a.theta_i, -a.phi_i, a.theta_o, -a.phi_o};
    const brdf::StdAngles swapped{a.theta_o, a.phi_o, a.theta_i, a.phi_i};  // Helmholtz reciprocity
    for (const Mapping m : {Mapping::standard, Mapping::marschner, Mapping::halfdiff}) {
      EXPECT_LT((map_angles(m, rotated) - map_angles(m, a)).norm(), 1e-12) << mapping_name(m);
      EXPECT_LT((map_angles(m, mirrored) - map_angles(m, a)).norm(), 1e-12) << mapping_name(m);
    }
    // M_m (eqs 5.6-5.7) and M_h identify reciprocal configurations; M_s does not.
    EXPECT_LT((map_angles(Mapping::marschner, swapped) - map_angles(Mapping::marschner, a)).norm(), 1e-12);
    EXPECT_LT((map_angles(Mapping::halfdiff, swapped) - map_angles(Mapping::halfdiff, a)).norm(), 1e-9);
    if (std::abs(a.theta_i - a.theta_o) > 1e-3) {
      EXPECT_GT((map_angles(Mapping::standard, swapped) - map_angles(Mapping::standard, a)).norm(), 1e-4);
    }
  }
  EXPECT_THROW(parse_mapping("polar"), UsageError);
  EXPECT_THROW(parse_weights("median"), UsageError);
}

TEST(Resampler, NeighboursEqualABruteForceSearch) {
  std::mt19937_64 rng(2);
  std::vector<double> angles;
  std::vector<float> values;
  for (int i = 0; i < 3000; ++i) {
    const auto a = random_angles(rng);
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    values.push_back(float(i));
  }
  for (const Mapping m : {Mapping::standard, Mapping::marschner, Mapping::halfdiff}) {
    const Resampler r(angles, values, 1, {.mapping = m, .k = 7});
    std::vector<std::size_t> index;
    std::vector<double> dist2;
    for (int q = 0; q < 50; ++q) {
      const auto at = random_angles(rng);
      r.neighbours(at, index, dist2);
      std::vector<std::pair<double, std::size_t>> all;
      const Eigen::Vector3d p = map_angles(m, at);
      for (std::size_t i = 0; i < 3000; ++i)
        all.push_back({(map_angles(m, {angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]}) - p).squaredNorm(), i});
      std::sort(all.begin(), all.end());
      ASSERT_EQ(index.size(), 7u);
      for (std::size_t j = 0; j < 7; ++j) EXPECT_NEAR(dist2[j], all[j].first, 1e-12) << mapping_name(m);
      for (std::size_t j = 0; j < 6; ++j) EXPECT_EQ(index[j], all[j].second) << mapping_name(m);  // ties aside
    }
  }
}

TEST(Resampler, SamplesAtCellCentresAreReproducedExactlyWithOneNeighbour) {
  std::vector<double> angles;
  std::vector<float> values;
  std::vector<std::size_t> cells;
  for (std::size_t c = 0; c < brdf::kMerlCells; c += 97) {
    const brdf::MerlCell cell = brdf::merl_cell(c);
    if (!brdf::merl_cell_valid(cell)) continue;
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(cell));
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    values.push_back(float(c) * 0.5f);
    values.push_back(float(c) * 0.25f);
    cells.push_back(c);
  }
  for (const Weights w : {Weights::mean, Weights::shepard}) {
    const Resampler r(angles, values, 2, {.mapping = Mapping::standard, .k = 1, .weights = w, .max_gap = 10});
    std::vector<float> grid(2 * brdf::kMerlCells);
    r.fill_grid(grid);
    for (std::size_t j = 0; j < cells.size(); ++j) {
      ASSERT_EQ(grid[cells[j]], values[2 * j]) << cells[j];
      ASSERT_EQ(grid[brdf::kMerlCells + cells[j]], values[2 * j + 1]) << cells[j];
    }
  }
}

// Shepard weights are a convex combination: a constant is reproduced exactly, and a field linear in the
// mapped coordinates is reproduced to within its gradient times the distance of the farthest neighbour used.
TEST(Resampler, ShepardReproducesConstantsAndLinearFieldsToInterpolationAccuracy) {
  std::mt19937_64 rng(3);
  std::vector<double> angles;
  std::vector<float> values;
  const Eigen::Vector3d grad(0.3, -0.2, 0.1);
  for (int i = 0; i < 20000; ++i) {
    const auto a = random_angles(rng);
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    values.push_back(2.5f);
    values.push_back(float(1 + grad.dot(map_angles(Mapping::standard, a))));
  }
  const Resampler r(angles, values, 2, {.mapping = Mapping::standard, .k = 16, .weights = Weights::shepard, .power = 2});
  std::vector<float> out(2);
  std::vector<std::size_t> index;
  std::vector<double> dist2;
  std::uniform_real_distribution<double> t(0.2, 1.2), p(0.3, 2.8);
  for (int q = 0; q < 300; ++q) {
    const brdf::StdAngles at{t(rng), 0.0, t(rng), p(rng)};
    ASSERT_TRUE(r.predict(at, out));
    EXPECT_NEAR(out[0], 2.5f, 1e-6);
    r.neighbours(at, index, dist2);
    const double reach = std::sqrt(dist2.back());
    EXPECT_LE(std::abs(out[1] - (1 + grad.dot(map_angles(Mapping::standard, at)))), grad.norm() * reach + 1e-6);
  }
}

TEST(Resampler, CellsFarFromEverySampleHaveNoDataAndBadOptionsAreRefused) {
  std::vector<double> angles = {0.5, 0.0, 0.5, pi};
  std::vector<float> values = {1.0f};
  const Resampler r(angles, values, 1, {.k = 1, .max_gap = 0.1});
  std::vector<float> grid(brdf::kMerlCells);
  const std::size_t valid = r.fill_grid(grid);
  // Independently: a cell has data exactly when it is above the horizon and its centre lies within 0.1 rad
  // of the sample in (theta_i, theta_o, |phi_o - phi_i| folded to [0, pi]).
  std::size_t expect = 0;
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c) {
    const brdf::MerlCell cell = brdf::merl_cell(c);
    bool ok = brdf::merl_cell_valid(cell);
    if (ok) {
      const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(cell));
      double pd = std::fmod(std::abs(a.phi_o - a.phi_i), 2 * pi);
      if (pd > pi) pd = 2 * pi - pd;
      ok = std::hypot(a.theta_i - 0.5, a.theta_o - 0.5, pd - pi) <= 0.1;
    }
    expect += ok;
    ASSERT_EQ(grid[c] == 1.0f, ok) << c;
  }
  EXPECT_EQ(valid, expect);
  EXPECT_GT(valid, 0u);
  EXPECT_EQ(std::count(grid.begin(), grid.end(), -1.0f), std::ptrdiff_t(brdf::kMerlCells - valid));
  EXPECT_THROW(Resampler(angles, values, 1, {.k = 0}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 1, {.power = -1}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 2, {}), UsageError);
  EXPECT_THROW(Resampler({}, {}, 1, {}), InputError);
}

}  // namespace
}  // namespace specula::acquire
