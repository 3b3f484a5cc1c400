#include "specula/acquire/study.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "specula/acquire/scan.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

TEST(Study, ALambertianSphereIsAlbedoTimesCosine) {
  const Eigen::Vector3d l = Eigen::Vector3d(0.3, -0.4, 0.8).normalized();
  const SphereRender r = render_sphere(64, l, [](const brdf::IsoAngles&, double& f) {
    f = 0.7 / pi;
    return true;
  });
  std::size_t covered = 0;
  for (std::size_t p = 0; p < 64 * 64; ++p) {
    const double x = (double(p % 64) + 0.5) / 32 - 1, y = 1 - (double(p / 64) + 0.5) / 32;
    ASSERT_EQ(r.covered[p] != 0, x * x + y * y < 1);
    if (!r.covered[p]) continue;
    ++covered;
    const Eigen::Vector3d n(x, y, std::sqrt(1 - x * x - y * y));
    EXPECT_NEAR(r.value[p], 0.7 * std::max(0.0, n.dot(l)), 1e-12);
  }
  EXPECT_NEAR(double(covered), pi / 4 * 64 * 64, 40);
  EXPECT_THROW(render_sphere(0, l, {}), UsageError);
  EXPECT_THROW(render_sphere(8, Eigen::Vector3d::Zero(), {}), UsageError);
}

TEST(Study, LookupCellIsMerlsCell) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(0, pi);
  for (int i = 0; i < 200; ++i) {
    const brdf::IsoAngles a{t(rng), t(rng), p(rng)};
    EXPECT_EQ(
        merl_lookup_cell(a),
        brdf::merl_index(brdf::merl_cell(brdf::half_diff(brdf::StdAngles{a.theta_i, 1.0, a.theta_o, 1.0 + a.phi_d}))));
  }
}

// A Lambertian material is constant: any convex weights reconstruct it exactly, so every row of the study, and
// the grid of the model, must match the truth; a glossy one must not, and its error must be finite and reported.
TEST(Study, AConstantBrdfIsReconstructedExactlyAndAGlossyOneIsNot) {
  const WavelengthGrid g({550.0});
  ScanRig rig;
  rig.sphere_px = 40;
  rig.lights = 60;
  rig.light_step_deg = 2.5;
  const auto px = scan_pixels(rig);
  std::vector<double> angles;
  for (std::size_t j = 0; j < rig.lights; ++j) scan_light(rig, px, j, angles);
  const std::size_t n = angles.size() / 4;
  ASSERT_GT(n, 20000u);
  StudyOptions o;
  o.ks = {1, 8};
  o.render_size = 48;
  o.max_gap = 10;
  const brdf::Lambertian lambert(g, Eigen::VectorXd::Constant(1, 0.6));
  std::vector<float> values(n);
  brdf::evaluate_at(lambert, angles, values);
  const StudyOutput flat = resampling_study(lambert, 0, angles, values, o);
  ASSERT_EQ(flat.rows.size(), 3u * 3u);
  EXPECT_LT(flat.grid_l1, 1e-12);
  for (const auto& r : flat.rows) EXPECT_LT(r.max_error, 1e-6) << brdf::mapping_name(r.mapping) << " k " << r.k;
  const brdf::Ward ward(g, Eigen::VectorXd::Constant(1, 0.1), Eigen::VectorXd::Constant(1, 0.3),
                        Eigen::VectorXd::Constant(1, 0.1));
  brdf::evaluate_at(ward, angles, values);
  const StudyOutput glossy = resampling_study(ward, 0, angles, values, o);
  EXPECT_GT(glossy.grid_l1, 0);
  for (const auto& r : glossy.rows) {
    EXPECT_GT(r.l1, glossy.grid_l1 * 0.5) << brdf::mapping_name(r.mapping) << " k " << r.k;
    EXPECT_LT(r.l1, 0.2) << brdf::mapping_name(r.mapping) << " k " << r.k;
  }
  EXPECT_THROW(resampling_study(ward, 1, angles, values, o), UsageError);
}

}  // namespace
}  // namespace specula::acquire
