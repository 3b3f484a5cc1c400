// incidence_plane_angle: configurations placed on and off the plane by hand.
#include <gtest/gtest.h>

#include <numbers>

#include "specula/core/brdf_mapping.h"

using namespace specula;
using std::numbers::pi;

namespace {
constexpr double deg = pi / 180;
std::optional<double> at(double ti, double pi_, double to, double po, double theta_i = 45 * deg, double eps = 2 * deg) {
  return brdf::incidence_plane_angle(brdf::iso_angles({ti, pi_, to, po}), theta_i, eps);
}
}  // namespace

TEST(IncidencePlane, SignedOutgoingAngle) {
  // The viewer opposite the light (phi_o - phi_i = pi): towards the mirror direction, positive.
  ASSERT_TRUE(at(45 * deg, 0.3, 30 * deg, 0.3 + pi));
  EXPECT_DOUBLE_EQ(*at(45 * deg, 0.3, 30 * deg, 0.3 + pi), 30 * deg);
  // On the light's side (phi_o = phi_i): negative.
  EXPECT_DOUBLE_EQ(*at(45 * deg, -1.0, 60 * deg, -1.0), -60 * deg);
  // Within eps of theta_i and of the plane, either way round the circle.
  EXPECT_DOUBLE_EQ(*at(46.5 * deg, 0.0, 10 * deg, 2 * pi - 1.5 * deg), -10 * deg);
}

TEST(IncidencePlane, OffThePlaneOrTheAngle) {
  EXPECT_FALSE(at(45 * deg, 0.0, 30 * deg, pi / 2));   // across the plane
  EXPECT_FALSE(at(45 * deg, 0.0, 30 * deg, 3 * deg));  // just outside eps of phi_d = 0
  EXPECT_FALSE(at(48 * deg, 0.0, 30 * deg, pi));       // theta_i 3 degrees off
  EXPECT_TRUE(at(48 * deg, 0.0, 30 * deg, pi, 45 * deg, 4 * deg));
}
