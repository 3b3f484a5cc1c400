// The energy bound (acquire/energy_bound.h): the directional albedo against a closed form (a Lambertian's is its
// rho at every incidence) and against a brute-force integral over the outgoing hemisphere written here; the bound
// leaves a material within it bit for bit, and of a planted runaway scales exactly the runaway's cells, colour kept,
// until every incidence meets it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "codec/grid_fixture.h"
#include "specula/acquire/energy_bound.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<float> flat(std::size_t bands, std::vector<double> rho) {
  std::vector<float> g(bands * brdf::kMerlCells);
  for (std::size_t k = 0; k < bands; ++k)
    for (std::size_t c = 0; c < brdf::kMerlCells; ++c) g[k * brdf::kMerlCells + c] = float(rho[k] / kPi);
  return g;
}

std::vector<double> albedo(std::span<const float> g, std::size_t bands) {
  std::vector<double> rho(kAlbedoRows * bands);
  directional_albedo(g, bands, rho);
  return rho;
}

// The albedo at theta_i by the midpoint rule over cos-weighted outgoing directions: u = cos^2 theta_o uniform.
double brute_albedo(std::span<const float> g, std::size_t band, double theta_i) {
  constexpr int kU = 400, kPhi = 720;
  const Eigen::Vector3d wi(std::sin(theta_i), 0, std::cos(theta_i));
  double sum = 0;
  for (int iu = 0; iu < kU; ++iu)
    for (int ip = 0; ip < kPhi; ++ip) {
      const double mu = std::sqrt((iu + 0.5) / kU), phi = 2 * kPi * (ip + 0.5) / kPhi;
      const Eigen::Vector3d wo = brdf::direction(std::acos(mu), phi);
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::half_diff(wi, wo)));
      sum += std::max(0.0f, g[band * brdf::kMerlCells + cell]);
    }
  return sum * (0.5 / kU) * (2 * kPi / kPhi);  // d(projected solid angle) = du / 2 d phi
}

TEST(DirectionalAlbedo, LambertianIsItsRhoAtEveryIncidence) {
  const std::vector<float> g = flat(2, {0.8, 0.25});
  const std::vector<double> rho = albedo(g, 2);
  for (std::size_t r = 0; r < kAlbedoRows; ++r) {
    EXPECT_NEAR(rho[r * 2], 0.8, 0.8 * 2e-3) << "row " << r;
    EXPECT_NEAR(rho[r * 2 + 1], 0.25, 0.25 * 2e-3) << "row " << r;
  }
}

TEST(DirectionalAlbedo, WardMatchesABruteForceIntegralOverTheOutgoingHemisphere) {
  const store::Grid g = test::grid_of(test::ward(0.5, 0.1, 0.2, 0.15));
  const std::size_t bands = g.bands();
  const std::vector<double> rho = albedo(g.brdf, bands);
  for (const std::size_t r : {0, 30, 60, 75}) {
    const double want = brute_albedo(g.brdf, 4, (double(r) + 0.5) * kPi / 180);
    EXPECT_NEAR(rho[r * bands + 4], want, 0.01 * want) << "row " << r;
  }
}

TEST(BoundEnergy, LeavesAMaterialWithinTheBoundAsItIs) {
  for (const std::vector<double>& rho : {std::vector<double>{1.9, 0.4}, std::vector<double>{1.6, 5.0}}) {
    std::vector<float> g = flat(2, rho);  // 5.0 as if in another scale: its own median bounds it
    const std::vector<float> before = g;
    EXPECT_EQ(bound_energy(g, 2, {}), 0u);
    EXPECT_EQ(g, before);
  }
  const store::Grid ward = test::grid_of(test::ward(0.5, 0.1, 0.2, 0.15));
  std::vector<float> w = ward.brdf;
  EXPECT_EQ(bound_energy(w, ward.bands(), {}), 0u);
  EXPECT_EQ(w, ward.brdf);
}

TEST(BoundEnergy, CutsAPlantedRunawayUntilEveryIncidenceMeetsTheBound) {
  std::vector<float> g = flat(2, {0.3, 0.2});
  std::vector<std::uint8_t> planted(brdf::kMerlCells, 0);
  for (int th = 7; th <= 11; ++th)
    for (int td = 83; td <= 86; ++td)
      for (int pd = 0; pd < brdf::kMerlPhiD; ++pd) {
        const std::size_t c = brdf::merl_index({th, td, pd});
        planted[c] = 1;
        g[c] = 1e6f;
        g[brdf::kMerlCells + c] = 5e5f;
      }
  const std::vector<float> before = g;
  const std::vector<double> runaway = albedo(g, 2);
  ASSERT_GT(*std::max_element(runaway.begin(), runaway.end()), 10.0);
  const std::size_t scaled = bound_energy(g, 2, {});
  std::size_t changed = 0;
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c) {
    if (g[c] == before[c]) continue;
    ++changed;
    ASSERT_TRUE(planted[c]) << "cell " << c << " was not planted";
    EXPECT_NEAR(g[brdf::kMerlCells + c] / g[c], 0.5, 1e-6);
  }
  EXPECT_EQ(scaled, changed);
  EXPECT_GT(changed, 100u);
  const std::vector<double> rho = albedo(g, 2);  // the median albedo (0.3) doubled is below the floor: the bound is 2
  for (std::size_t r = 0; r < kAlbedoRows; ++r) EXPECT_LE(rho[r * 2], 2 + 1e-6) << "row " << r;
  EXPECT_GT(*std::max_element(rho.begin(), rho.end()), 2 - 2e-3);  // cut to the bound, not below it
}

TEST(BoundEnergy, RefusesBadSizesAndKappa) {
  std::vector<float> g = flat(1, {0.5});
  EXPECT_THROW(bound_energy(std::span<float>(g).first(100), 1, {}), UsageError);
  EXPECT_THROW(bound_energy(g, 1, {.kappa = 0}), UsageError);
  EXPECT_THROW(bound_energy(g, 1, {.floor = -1}), UsageError);
  std::vector<double> rho(3);
  EXPECT_THROW(directional_albedo(g, 1, rho), UsageError);
}

}  // namespace
}  // namespace specula::acquire
