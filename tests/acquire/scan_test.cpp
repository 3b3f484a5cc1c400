#include "specula/acquire/scan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

TEST(Scan, PixelsLieOnTheSphereAndTheSilhouetteHasTheAskedSize) {
  ScanRig rig;
  rig.sphere_px = 120;
  const std::vector<ScanPixel> px = scan_pixels(rig);
  const double r = sphere_radius(rig);
  const Eigen::Vector3d c(rig.off_axis, rig.off_axis_y, rig.distance);
  int xmin = 1 << 30, xmax = -(1 << 30);
  for (const ScanPixel& p : px) {
    EXPECT_NEAR((p.point - c).norm(), r, 1e-9);
    EXPECT_NEAR(p.normal.norm(), 1, 1e-12);
    EXPECT_GT(p.normal.dot(p.to_camera), 0);
    // The camera at the origin sees the point along to_camera.
    EXPECT_LT((p.point.normalized() + p.to_camera).norm(), 1e-12);
    xmin = std::min(xmin, p.x);
    xmax = std::max(xmax, p.x);
  }
  // About pi/4 of the bounding square, and sphere_px across (within a pixel or two: perspective, pixel centres).
  EXPECT_NEAR(double(px.size()), pi / 4 * 120 * 120, 0.03 * pi / 4 * 120 * 120);
  EXPECT_NEAR(double(xmax - xmin + 1), 120, 2.5);
  rig.sphere_px = 0;
  EXPECT_THROW(scan_pixels(rig), UsageError);
  rig.sphere_px = 100;
  rig.light_distance = 0.001;
  EXPECT_THROW(scan_pixels(rig), UsageError);
}

TEST(Scan, LightsMoveOnAnArcInEqualStepsAndSamplesHaveTheRightAngles) {
  const ScanRig rig;
  const Eigen::Vector3d c(rig.off_axis, rig.off_axis_y, rig.distance);
  const Eigen::Vector3d to_camera = (-c).normalized();
  for (std::size_t j = 0; j + 1 < rig.lights; j += 20) {
    const Eigen::Vector3d a = light_position(rig, j) - c, b = light_position(rig, j + 1) - c;
    EXPECT_NEAR(a.norm(), rig.light_distance, 1e-12);
    EXPECT_NEAR(std::acos(a.normalized().dot(b.normalized())), pi / 180, 1e-9);
    EXPECT_NEAR(std::acos(a.normalized().dot(to_camera)) * 180 / pi, std::min(180.0, rig.first_light_deg + double(j)),
                1e-6);
  }
  // The angles of a sample are those of its vectors: cosines against the normal and the angle between the
  // projections on the tangent plane.
  const std::vector<ScanPixel> px = scan_pixels(rig);
  const Eigen::Vector3d light = light_position(rig, 30);
  std::size_t lit = 0;
  for (std::size_t i = 0; i < px.size(); i += 37) {
    brdf::StdAngles s;
    const Eigen::Vector3d wi = (light - px[i].point).normalized();
    const bool ok = scan_angles(px[i], light, s);
    ASSERT_EQ(ok, wi.dot(px[i].normal) > 0);
    if (!ok) continue;
    ++lit;
    EXPECT_NEAR(std::cos(s.theta_i), wi.dot(px[i].normal), 1e-12);
    EXPECT_NEAR(std::cos(s.theta_o), px[i].to_camera.dot(px[i].normal), 1e-12);
    const Eigen::Vector3d a = (wi - wi.dot(px[i].normal) * px[i].normal).normalized();
    const Eigen::Vector3d b = (px[i].to_camera - px[i].to_camera.dot(px[i].normal) * px[i].normal).normalized();
    EXPECT_NEAR(std::cos(s.phi_o - s.phi_i), a.dot(b), 1e-9);
  }
  EXPECT_GT(lit, 100u);
  // As the light goes round behind the sphere, fewer points are lit.
  std::vector<double> angles;
  const std::size_t front = scan_light(rig, px, 0, angles), back = scan_light(rig, px, rig.lights - 1, angles);
  EXPECT_GT(front, 3 * back);
  EXPECT_EQ(angles.size(), 4 * (front + back));
}

}  // namespace
}  // namespace specula::acquire
