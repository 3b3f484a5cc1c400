#include "specula/codec/suite.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>
#include <random>

#include "grid_fixture.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "suite_reference.h"

namespace specula::codec {
namespace {

using std::numbers::pi;
using test::brute_force;
using test::view_axes;
constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid& kGrid = test::kCodecBands;

const store::Grid& ward() {
  static const store::Grid g =
      test::grid_of(brdf::Ward(kGrid, Eigen::VectorXd::LinSpaced(7, 0.05, 0.4), Eigen::VectorXd::Constant(7, 0.15),
                               Eigen::VectorXd::Constant(7, 0.2)));
  return g;
}

const LightingSuite& suite() {
  static const LightingSuite s(kGrid, {.size = 32});
  return s;
}

// A grid of value v_b in every cell, below the horizon too (so no cell renders black).
store::Grid constant_grid(const Eigen::VectorXd& v) {
  store::Grid g;
  g.wavelengths = kGrid;
  g.brdf.resize(7 * N);
  for (std::size_t k = 0; k < 7; ++k) std::fill_n(g.brdf.begin() + std::ptrdiff_t(k * N), N, float(v[Eigen::Index(k)]));
  return g;
}

TEST(Suite, HasTheDocumentedConditions) {
  const auto& c = suite().conditions();
  ASSERT_EQ(c.size(), 38u);  // 2 views x (environment + 9 directions x 2 illuminants)
  std::size_t env = 0, d65 = 0, a = 0, past_limb = 0;
  for (const auto& x : c) {
    env += x.light == "environment";
    d65 += x.light == "D65";
    a += x.light == "A";
    past_limb += x.elevation_deg > 100 && x.elevation_deg < 110;
  }
  EXPECT_EQ(env, 2u);
  EXPECT_EQ(d65, 18u);
  EXPECT_EQ(a, 18u);
  EXPECT_EQ(past_limb, 8u);
}

TEST(Suite, RendererMatchesABruteForceEvaluationOnPixelsOfEveryCondition) {
  const SuiteRenders r = suite().render(ward());
  const auto& pixels = suite().pixels();
  std::size_t checked = 0, off = 0;
  for (std::size_t c = 0; c < suite().conditions().size(); ++c)
    for (std::size_t i = 0; i < pixels.size(); i += pixels.size() / 7) {
      const Eigen::Vector3d want = suite().to_xyz() * brute_force(ward(), suite(), c, pixels[i]);
      const Eigen::Vector3d got(r.xyz[c][3 * i], r.xyz[c][3 * i + 1], r.xyz[c][3 * i + 2]);
      ++checked;
      // A direction pair within float rounding of a cell boundary may land in the neighbouring cell.
      if ((got - want).norm() > 1e-4 * std::max(1e-3, want.norm())) ++off;
    }
  EXPECT_GT(checked, 250u);
  EXPECT_LE(off, checked / 100) << off << " of " << checked << " pixels differ from the brute-force evaluation";
}

TEST(Suite, LambertianSphereUnderADirectionalLightIsRhoOverPiTimesCosTimesE) {
  const Eigen::VectorXd rho = Eigen::VectorXd::LinSpaced(7, 0.2, 0.8);
  const store::Grid g = constant_grid(rho / pi);
  const SuiteRenders r = suite().render(g);
  for (std::size_t c = 0; c < suite().conditions().size(); ++c) {
    const SuiteCondition& cond = suite().conditions()[c];
    if (cond.light == "environment") continue;
    Eigen::Vector3d ax, ay, az;
    view_axes(cond.view, ax, ay, az);
    const Eigen::VectorXd e = illuminant(cond.light, kGrid);
    for (std::size_t i = 0; i < suite().pixels().size(); ++i) {
      const std::size_t pix = suite().pixels()[i];
      const double px = 2 * (double(pix % 32) + 0.5) / 32 - 1, py = 1 - 2 * (double(pix / 32) + 0.5) / 32;
      const Eigen::Vector3d n = px * ax + py * ay + std::sqrt(1 - px * px - py * py) * az;
      const double cos_i = std::max(0.0, n.dot(cond.direction));
      const Eigen::Vector3d want = suite().to_xyz() * (rho.cwiseProduct(e) / pi * cos_i);
      for (std::size_t k = 0; k < 3; ++k)
        ASSERT_NEAR(r.xyz[c][3 * i + k], want[Eigen::Index(k)], 2e-6 * want.norm() + 1e-9) << cond.name;
    }
  }
}

TEST(Suite, AlbedoOfALambertianGridIsRho) {
  const std::array<double, 4> a = suite_albedo(constant_grid(Eigen::VectorXd::Constant(7, 0.6 / pi)));
  for (const double v : a) EXPECT_NEAR(v, 0.6, 1e-6);
}

TEST(Suite, AlbedoMatchesAMonteCarloIntegral) {
  const store::Grid g = test::grid_of(brdf::Ward(kGrid, Eigen::VectorXd::Constant(7, 0.3),
                                                 Eigen::VectorXd::Constant(7, 0.2), Eigen::VectorXd::Constant(7, 0.3)));
  const std::array<double, 4> q = suite_albedo(g);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u01(0, 1);
  for (std::size_t a = 0; a < kSuiteAlbedoAngles.size(); ++a) {
    // Cosine-weighted directions: the estimator of the albedo is pi f.
    const double ti = kSuiteAlbedoAngles[a] * pi / 180;
    double sum = 0, sq = 0;
    const std::size_t n = 200000;
    for (std::size_t i = 0; i < n; ++i) {
      const double r = std::sqrt(u01(rng)), phi = 2 * pi * u01(rng);
      const brdf::StdAngles ang{ti, 0, std::asin(std::min(1.0, r)), phi};
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(ang));
      const double f = g.brdf[cell] >= 0 ? pi * double(g.brdf[cell]) : 0.0;  // grey: band 0 stands for all
      sum += f;
      sq += f * f;
    }
    const double mean = sum / double(n), se = std::sqrt((sq / double(n) - mean * mean) / double(n));
    EXPECT_NEAR(q[a], mean, 4 * se + 0.01 * mean) << "theta_i " << kSuiteAlbedoAngles[a];
  }
}

TEST(Suite, IdenticalGridsDifferByNothingAndHolesAreCountedAndSeen) {
  const SuiteDiff same = suite_diff(ward(), ward(), suite());
  EXPECT_EQ(same.de00_mean, 0);
  EXPECT_EQ(same.de00_max, 0);
  EXPECT_EQ(same.hole_cells, 0u);
  EXPECT_EQ(same.rel_rms_cos, 0);
  store::Grid holed = ward();
  std::uint64_t removed = 0;
  for (std::size_t c = 0; c < N; ++c)  // every cell with theta_d index 40..49 loses its data
    if (brdf::merl_cell(c).theta_d >= 40 && brdf::merl_cell(c).theta_d < 50 && ward().brdf[c] >= 0) {
      ++removed;
      for (std::size_t k = 0; k < 7; ++k) holed.brdf[k * N + c] = -1;
    }
  const SuiteDiff d = suite_diff(ward(), holed, suite());
  EXPECT_EQ(d.hole_cells, removed);
  EXPECT_EQ(d.extra_cells, 0u);
  EXPECT_GT(d.hole_pixels, 0u);
  EXPECT_GT(d.de00_mean, 0.1);
  EXPECT_GT(d.rel_rms_cos, 0);
  // The reverse comparison: the holes are the reference's now, so the other grid's data there is extra.
  const SuiteDiff r = suite_diff(holed, ward(), suite());
  EXPECT_EQ(r.hole_cells, 0u);
  EXPECT_EQ(r.extra_cells, removed);
}

TEST(Suite, PooledStatisticsAreThoseOfAllConditionsPixels) {
  store::Grid b = ward();
  for (auto& v : b.brdf)
    if (v >= 0) v *= 1.05f;
  const SuiteDiff d = suite().compare(suite().render(ward()), suite().render(b), true);
  double sum = 0;
  std::size_t n = 0;
  double worst = 0;
  for (std::size_t c = 0; c < d.conditions.size(); ++c) {
    for (std::size_t p = 0; p < suite().pixels().size(); ++p)
      if (suite().lit(c)[p]) sum += d.de00[c][p], ++n;
    worst = std::max(worst, d.conditions[c].de00_mean);
  }
  EXPECT_EQ(n, d.pixels + d.unseen_pixels);
  EXPECT_NEAR(d.de00_mean, sum / double(d.pixels), 1e-9 * d.de00_mean);
  EXPECT_EQ(d.conditions[d.worst].de00_mean, worst);
  EXPECT_GT(d.de00_mean, 0);
  EXPECT_LE(d.de00_p95, d.de00_max);
}

TEST(Suite, RenderingDoesNotDependOnTheThreadCount) {
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const SuiteRenders one = suite().render(ward());
  omp_set_num_threads(3);
  const SuiteRenders three = suite().render(ward());
  omp_set_num_threads(threads);
  EXPECT_EQ(one.xyz, three.xyz);
}

TEST(Suite, RefusesAGridOnOtherWavelengths) {
  store::Grid g = ward();
  g.wavelengths = WavelengthGrid::range(400, 700, 50);
  EXPECT_THROW(suite().render(g), InputError);
  EXPECT_THROW(LightingSuite(kGrid, {.size = 4}), UsageError);
}

}  // namespace
}  // namespace specula::codec
