#include "specula/codec/diff.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>

#include "grid_fixture.h"
#include "specula/codec/environment.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid& kGrid = test::kCodecBands;
using test::grid_of;

const store::Grid& ward() {
  static const store::Grid g =
      grid_of(brdf::Ward(kGrid, Eigen::VectorXd::LinSpaced(7, 0.05, 0.4), Eigen::VectorXd::Constant(7, 0.1),
                         Eigen::VectorXd::Constant(7, 0.1)));
  return g;
}

TEST(Diff, IdenticalGridsDifferByNothing) {
  const GridDiff d = diff_grids(ward(), ward(), default_environment(kGrid), {.size = 48});
  EXPECT_GT(d.cells, 1000000u);
  EXPECT_EQ(d.rms, 0);
  EXPECT_EQ(d.max_abs, 0);
  EXPECT_EQ(d.rel_rms_cos, 0);
  EXPECT_EQ(d.de00_mean, 0);
  EXPECT_EQ(d.de00_p95, 0);
}

TEST(Diff, AScaledGridHasTheScaleAsItsRelativeErrorAndClosedFormRms) {
  store::Grid b = ward();
  const double e = 0.01;
  for (auto& v : b.brdf)
    if (v >= 0) v = float(double(v) * (1 + e));
  const GridDiff d = diff_grids(ward(), b, default_environment(kGrid), {.size = 48});
  // Independent sums over the cells.
  double sq = 0, mx = 0;
  std::uint64_t n = 0;
  for (std::size_t c = 0; c < N; ++c) {
    if (ward().brdf[c] < 0) continue;
    ++n;
    for (std::size_t k = 0; k < 7; ++k) {
      const double diff = double(b.brdf[k * N + c]) - double(ward().brdf[k * N + c]);
      sq += diff * diff;
      mx = std::max(mx, std::abs(diff));
    }
  }
  EXPECT_EQ(d.cells, n);
  EXPECT_NEAR(d.rms, std::sqrt(sq / double(n * 7)), 1e-9 * d.rms);
  EXPECT_DOUBLE_EQ(d.max_abs, mx);
  EXPECT_NEAR(d.rel_rms_cos, e, 1e-6);  // float32 rounding of the scaled values
  EXPECT_GT(d.de00_mean, 0);
  EXPECT_LT(d.de00_mean, 1);
}

// Cells valid in one grid only are counted and left out of every value metric.
TEST(Diff, CellsValidInOneGridOnlyAreCountedNotCompared) {
  store::Grid b = ward();
  std::uint64_t cut = 0;
  for (std::size_t c = 0; c < N; c += 997) {
    if (b.brdf[c] < 0) continue;
    ++cut;
    b.brdf[c] = -1.0f;         // one band without data makes the whole cell invalid
    b.brdf[3 * N + c] = 1e6f;  // and what the other bands hold no longer matters
  }
  const GridDiff d = diff_grids(ward(), b, uniform_environment(kGrid, Eigen::VectorXd::Ones(7)), {.size = 16});
  EXPECT_EQ(d.only_a, cut);
  EXPECT_EQ(d.only_b, 0u);
  EXPECT_EQ(d.rms, 0);
  EXPECT_EQ(d.max_abs, 0);
  EXPECT_EQ(d.rel_rms_cos, 0);
  const GridDiff r = diff_grids(b, ward(), uniform_environment(kGrid, Eigen::VectorXd::Ones(7)), {.size = 16});
  EXPECT_EQ(r.only_b, cut);
  EXPECT_EQ(r.cells, d.cells);
}

// Two grey Lambertians under uniform light: the viewer-facing pixel of an odd-sized sphere is exact (see
// environment_test.cpp), so its CIELAB is L* = 116 (rho)^(1/3) - 16, a* = b* = 0 against the white, and its
// CIEDE2000 is that of the two greys.
TEST(Diff, TwoGreysDifferAsTheirLightnessesPredict) {
  const store::Grid a = grid_of(brdf::Lambertian(kGrid, Eigen::VectorXd::Constant(7, 0.5)));
  const store::Grid b = grid_of(brdf::Lambertian(kGrid, Eigen::VectorXd::Constant(7, 0.4)));
  const GridDiff d = diff_grids(a, b, uniform_environment(kGrid, Eigen::VectorXd::LinSpaced(7, 1, 3)), {.size = 33});
  const double la = 116 * std::cbrt(0.5) - 16, lb = 116 * std::cbrt(0.4) - 16;
  const double expect = ciede2000(Eigen::Vector3d(la, 0, 0), Eigen::Vector3d(lb, 0, 0));
  EXPECT_NEAR(d.de00[33 * 33 / 2], expect, 2e-3);
  EXPECT_GT(expect, 4);
  EXPECT_LE(d.de00_mean, d.de00_p95);
  EXPECT_LE(d.de00_p95, d.de00_max);
  // rel_rms_cos of a constant ratio is that ratio's distance from 1; rms and max are the albedo step / pi.
  EXPECT_NEAR(d.rel_rms_cos, 0.2, 1e-6);
  EXPECT_NEAR(d.max_abs, 0.1 / std::numbers::pi, 1e-7);
  EXPECT_NEAR(d.rms, 0.1 / std::numbers::pi, 1e-7);
}

TEST(Diff, ResultsDoNotDependOnTheThreadCount) {
  store::Grid b = ward();
  for (std::size_t i = 0; i < b.brdf.size(); i += 7)
    if (b.brdf[i] >= 0) b.brdf[i] *= 1.003f;
  const Environment env = default_environment(kGrid);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const GridDiff one = diff_grids(ward(), b, env, {.size = 24});
  omp_set_num_threads(3);
  const GridDiff three = diff_grids(ward(), b, env, {.size = 24});
  omp_set_num_threads(threads);
  EXPECT_EQ(one.rms, three.rms);
  EXPECT_EQ(one.rel_rms_cos, three.rel_rms_cos);
  EXPECT_EQ(one.max_abs, three.max_abs);
  EXPECT_EQ(one.de00, three.de00);
}

TEST(Diff, MismatchedWavelengthsNameBothGrids) {
  const store::Grid g =
      grid_of(brdf::Lambertian(WavelengthGrid::range(400, 700, 50), Eigen::VectorXd::Constant(7, 0.5)));
  const std::string text = test::input_error_text([&] { diff_grids(g, ward(), default_environment(kGrid)); });
  EXPECT_NE(text.find("400-700"), std::string::npos) << text;
  EXPECT_NE(text.find("420-720"), std::string::npos) << text;
  EXPECT_THROW(diff_grids(ward(), ward(), default_environment(kGrid), {.size = 2}), UsageError);
  // Light from behind only: no white to measure colour against.
  Environment back = uniform_environment(kGrid, Eigen::VectorXd::Zero(7));
  back.sun_direction = {0, 0, -1};
  back.sun_irradiance = Eigen::VectorXd::Ones(7);
  EXPECT_NE(test::input_error_text([&] { diff_grids(ward(), ward(), back, {.size = 16}); }).find("no light"),
            std::string::npos);
}

}  // namespace
}  // namespace specula::codec
