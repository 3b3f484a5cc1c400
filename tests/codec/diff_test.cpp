#include "codec/diff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "codec/environment.h"
#include "codec/spectral_grid.h"
#include "core/brdf_models.h"
#include "core/colour.h"
#include "core/error.h"
#include "store/io/exr.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid kGrid = WavelengthGrid::range(420, 720, 50);

store::Grid grid_of(const brdf::SpectralModel& model) {
  store::Grid g;
  g.wavelengths = model.wavelengths();
  g.brdf.resize(model.bands() * N);
  brdf::evaluate_grid(model, g.brdf);
  return g;
}

const store::Grid& ward() {
  static const store::Grid g = grid_of(brdf::Ward(kGrid, Eigen::VectorXd::LinSpaced(7, 0.05, 0.4),
                                                  Eigen::VectorXd::Constant(7, 0.1), Eigen::VectorXd::Constant(7, 0.1)));
  return g;
}

Environment uniform(const Eigen::VectorXd& l) {
  Environment e;
  e.wavelengths = kGrid;
  e.width = 64;
  e.height = 32;
  for (std::size_t p = 0; p < e.width * e.height; ++p)
    for (Eigen::Index k = 0; k < l.size(); ++k) e.radiance.push_back(float(l[k]));
  return e;
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

// A Lambertian surface under uniform radiance L reflects rho * L wherever it faces: the integral of
// cos(theta) over the hemisphere is pi. The 32 x 16 direction quadrature (regions of 11.25 degrees whose
// horizon cuts are counted whole or not at all) keeps that integral within a few per cent.
TEST(Environment, ALambertianSphereUnderUniformLightShowsRhoTimesL) {
  const Eigen::VectorXd rho = Eigen::VectorXd::LinSpaced(7, 0.2, 0.8), l = Eigen::VectorXd::LinSpaced(7, 1.0, 2.0);
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, rho));
  const SphereRenders r = render_spheres({&g}, uniform(l), 64);
  const SpectrumToXyz to_xyz(kGrid, SpectrumKind::radiance, Eigen::VectorXd::Ones(7));
  const Eigen::Vector3d expect = to_xyz.weights() * rho.cwiseProduct(l);
  std::size_t checked = 0;
  for (std::size_t p = 0; p < 64 * 64; ++p) {
    if (!r.covered[p]) continue;
    const double y = (p / 64 + 0.5) / 32 - 1, x = (p % 64 + 0.5) / 32 - 1;
    if (x * x + y * y > 0.9) continue;  // the rim's cells are half below the horizon
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.xyz[0][3 * p + std::size_t(c)], expect[c], 0.04 * expect[c]) << p;
    ++checked;
  }
  EXPECT_GT(checked, 2500u);
  // The white is a Lambertian of albedo 1 facing the viewer: the same quadrature, rho = 1.
  const Eigen::Vector3d white = to_xyz.weights() * l;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.white[c], white[c], 0.04 * white[c]);
}

TEST(Environment, AnRgbExrIsUpliftedToSpectraThatGiveItsRgbBack) {
  test::ScratchDir dir;
  const auto path = dir / "env.exr";
  std::vector<float> rgb;
  for (std::size_t p = 0; p < 64 * 32; ++p)
    for (const float v : {0.3f + 0.001f * float(p % 64), 0.5f, 0.2f}) rgb.push_back(v);
  store::write_exr_rgb(path, 64, 32, rgb);
  std::size_t w = 0, h = 0;
  const std::vector<float> stored = store::read_exr_rgb(path, w, h);  // half floats as written
  const Environment e = read_environment(path, WavelengthGrid::range(420, 720, 10));
  ASSERT_EQ(e.width, 32u);
  ASSERT_EQ(e.height, 16u);
  const auto weights = rgb_weights(e.wavelengths, Eigen::VectorXd::Ones(31));
  // Region (0, 0) averages pixels 0-1 of rows 0-1: their RGB, weighted by sin(theta) of each row.
  Eigen::Vector3d expect = Eigen::Vector3d::Zero();
  double wsum = 0;
  for (std::size_t y = 0; y < 2; ++y) {
    const double s = std::sin(std::numbers::pi * (double(y) + 0.5) / 32);
    for (std::size_t x = 0; x < 2; ++x) {
      for (int c = 0; c < 3; ++c) expect[c] += s * stored[3 * (y * 64 + x) + std::size_t(c)];
      wsum += s;
    }
  }
  expect /= wsum;
  const Eigen::Map<const Eigen::VectorXf> spectrum(e.radiance.data(), 31);
  EXPECT_LT((weights * spectrum.cast<double>() - expect).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_GE(spectrum.minCoeff(), 0.0f);
}

TEST(Environment, BadEnvironmentsAndMismatchedGridsAreRefused) {
  test::ScratchDir dir;
  const auto path = dir / "neg.exr";
  std::vector<float> rgb(3 * 8 * 4, 0.5f);
  rgb[5] = -1;
  store::write_exr_rgb(path, 8, 4, rgb);
  EXPECT_NE(test::input_error_text([&] { read_environment(path, kGrid); }).find("neg.exr"), std::string::npos);
  EXPECT_THROW(read_environment(dir / "missing.exr", kGrid), InputError);
  const store::Grid g = grid_of(brdf::Lambertian(WavelengthGrid::range(400, 700, 50), Eigen::VectorXd::Constant(7, 0.5)));
  EXPECT_THROW(render_spheres({&g}, default_environment(kGrid), 32), InputError);
  EXPECT_THROW(diff_grids(g, ward(), default_environment(kGrid)), InputError);
  EXPECT_THROW(render_spheres({&ward()}, default_environment(kGrid), 4), UsageError);
}

}  // namespace
}  // namespace specula::codec
