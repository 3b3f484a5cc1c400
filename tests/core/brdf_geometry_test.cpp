#include "specula/core/brdf_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace specula::brdf {
namespace {

using std::numbers::pi;
constexpr double kDeg = pi / 180;

double wrap(double a) { return std::remainder(a, 2 * pi); }

Eigen::Vector3d random_upper(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  // Uniform on the hemisphere, away from the pole and the horizon where phi degenerates.
  const double z = 0.02 + 0.96 * u(rng);
  return direction(std::acos(z), (2 * u(rng) - 1) * pi);
}

TEST(BrdfGeometry, DirectionAndSphericalAreInverse) {
  std::mt19937 rng(11);
  for (int n = 0; n < 1000; ++n) {
    const Eigen::Vector3d v = random_upper(rng);
    const Eigen::Vector2d s = spherical(v);
    EXPECT_LT((direction(s[0], s[1]) - v).norm(), 1e-13);
    EXPECT_NEAR(v.norm(), 1.0, 1e-15);
  }
  EXPECT_LT((direction(pi / 2, pi / 2) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-15);
  EXPECT_EQ(spherical(Eigen::Vector3d(0, 0, 2))[1], 0.0);
}

TEST(BrdfGeometry, HalfDiffRoundTripsDirections) {
  std::mt19937 rng(12);
  for (int n = 0; n < 2000; ++n) {
    const Eigen::Vector3d wi = random_upper(rng), wo = random_upper(rng);
    const HalfDiff h = half_diff(wi, wo);
    Eigen::Vector3d wi2, wo2;
    directions(h, wi2, wo2);
    EXPECT_LT((wi2 - wi).norm(), 1e-12);
    EXPECT_LT((wo2 - wo).norm(), 1e-12);
    // Independent facts: the half vector bisects, and theta_d is the angle between it and either direction.
    const Eigen::Vector3d half = (wi + wo).normalized();
    EXPECT_NEAR(std::cos(h.theta_h), half.z(), 1e-12);
    EXPECT_NEAR(std::cos(h.theta_d), wi.dot(half), 1e-12);
    EXPECT_NEAR(std::cos(h.theta_d), wo.dot(half), 1e-12);
  }
}

TEST(BrdfGeometry, HalfDiffAnglesRoundTrip) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0, 1);
  for (int n = 0; n < 2000; ++n) {
    const HalfDiff h{0.01 + 1.5 * u(rng), (2 * u(rng) - 1) * pi, 0.01 + 1.5 * u(rng), (2 * u(rng) - 1) * pi};
    Eigen::Vector3d wi, wo;
    directions(h, wi, wo);
    const HalfDiff g = half_diff(wi, wo);
    EXPECT_NEAR(g.theta_h, h.theta_h, 1e-11);
    EXPECT_NEAR(g.theta_d, h.theta_d, 1e-11);
    EXPECT_NEAR(wrap(g.phi_h - h.phi_h), 0.0, 1e-11);
    EXPECT_NEAR(wrap(g.phi_d - h.phi_d), 0.0, 1e-11);
  }
}

TEST(BrdfGeometry, StdAnglesRoundTrip) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> u(0, 1);
  for (int n = 0; n < 2000; ++n) {
    const StdAngles a{0.02 + 1.5 * u(rng), (2 * u(rng) - 1) * pi, 0.02 + 1.5 * u(rng), (2 * u(rng) - 1) * pi};
    const StdAngles b = std_angles(half_diff(a));
    EXPECT_NEAR(b.theta_i, a.theta_i, 1e-11);
    EXPECT_NEAR(b.theta_o, a.theta_o, 1e-11);
    EXPECT_NEAR(wrap(b.phi_i - a.phi_i), 0.0, 1e-11);
    EXPECT_NEAR(wrap(b.phi_o - a.phi_o), 0.0, 1e-11);
  }
}

// Mirror reflection: the half vector is the normal, so theta_h = 0 and theta_d = theta_i; phi_h is then
// arbitrary but phi_d = phi_i - phi_h still holds.
TEST(BrdfGeometry, MirrorConfiguration) {
  for (double theta : {5.5, 30.5, 61.5, 85.5})  // mid-bin: whole degrees are bin edges
    for (double phi : {0.0, 40.0, -120.0}) {
      const StdAngles a{theta * kDeg, phi * kDeg, theta * kDeg, (phi + 180) * kDeg};
      const HalfDiff h = half_diff(a);
      EXPECT_NEAR(h.theta_h, 0.0, 1e-7);
      EXPECT_NEAR(h.theta_d, theta * kDeg, 1e-12);
      EXPECT_NEAR(wrap(h.phi_d + h.phi_h - phi * kDeg), 0.0, 1e-12);
      EXPECT_EQ(merl_cell(a).theta_h, 0);
      EXPECT_EQ(merl_cell(a).theta_d, int(theta));
    }
}

// Normal incidence towards theta_o: the half vector sits at theta_o / 2 in the plane of wo, and the
// incident direction, seen from it, leans back by theta_o / 2 (phi_d = pi).
TEST(BrdfGeometry, NormalIncidenceClosedForm) {
  const HalfDiff h = half_diff(StdAngles{0, 0, 60 * kDeg, 90 * kDeg});
  EXPECT_NEAR(h.theta_h, 30 * kDeg, 1e-12);
  EXPECT_NEAR(h.phi_h, 90 * kDeg, 1e-12);
  EXPECT_NEAR(h.theta_d, 30 * kDeg, 1e-12);
  EXPECT_NEAR(std::abs(h.phi_d), pi, 1e-12);
}

TEST(BrdfGeometry, IndexOfCellCentreIsTheCell) {
  for (int i = 0; i < kMerlThetaH; ++i)
    for (int j = 0; j < kMerlThetaD; ++j)
      for (int k = 0; k < kMerlPhiD; k += 7) {
        const MerlCell c{i, j, k};
        const MerlCell back = merl_cell(merl_cell_centre(c));
        ASSERT_EQ(back.theta_h, i);
        ASSERT_EQ(back.theta_d, j);
        ASSERT_EQ(back.phi_d, k);
        const MerlCell linear = merl_cell(merl_index(c));
        ASSERT_EQ(linear.theta_h, i);
        ASSERT_EQ(linear.theta_d, j);
        ASSERT_EQ(linear.phi_d, k);
      }
}

// Through the standard angles too (phi_h = 0 at the centre), for the cells whose centre is above the horizon.
TEST(BrdfGeometry, StdAnglesOfCellCentreLookUpTheCell) {
  std::mt19937 rng(15);
  std::uniform_int_distribution<std::size_t> cell(0, kMerlCells - 1);
  int checked = 0;
  while (checked < 3000) {
    const MerlCell c = merl_cell(cell(rng));
    if (!merl_cell_valid(c) || c.theta_h == 0) continue;
    const MerlCell back = merl_cell(std_angles(merl_cell_centre(c)));
    ASSERT_EQ(merl_index(back), merl_index(c)) << c.theta_h << " " << c.theta_d << " " << c.phi_d;
    ++checked;
  }
}

// Values worked by hand from BRDFRead.cpp's formulas.
TEST(BrdfGeometry, KnownIndices) {
  // theta_h = 20 deg: floor(90 sqrt(20/90)) = floor(42.43) = 42; theta_d = 40.3 deg -> 40; phi_d = 50.2 deg -> 50.
  const HalfDiff h{20 * kDeg, 10 * kDeg, 40.3 * kDeg, 50.2 * kDeg};
  const MerlCell c = merl_cell(h);
  EXPECT_EQ(c.theta_h, 42);
  EXPECT_EQ(c.theta_d, 40);
  EXPECT_EQ(c.phi_d, 50);
  EXPECT_EQ(merl_index(c), 50u + 180u * (40u + 90u * 42u));
  // Reciprocity: phi_d - 180 deg lands in the same bin.
  EXPECT_EQ(merl_phi_d_index(-129.8 * kDeg), 50);
  // Via the standard angles of those half/diff angles.
  EXPECT_EQ(merl_index(merl_cell(std_angles(h))), merl_index(c));
  // Edges: theta_h index 1 begins at (1/90)^2 * 90 deg = 1/90 deg; clamping at the top of each range.
  EXPECT_EQ(merl_theta_h_index(0.0), 0);
  EXPECT_EQ(merl_theta_h_index(0.9 / 90 * kDeg), 0);
  EXPECT_EQ(merl_theta_h_index(1.1 / 90 * kDeg), 1);
  EXPECT_EQ(merl_theta_h_index(pi / 2), 89);
  EXPECT_EQ(merl_theta_d_index(pi / 2), 89);
  EXPECT_EQ(merl_theta_d_index(-0.1), 0);
  EXPECT_EQ(merl_phi_d_index(pi), 179);
  EXPECT_EQ(merl_phi_d_index(0.0), 0);
  EXPECT_EQ(merl_index(MerlCell{89, 89, 179}), kMerlCells - 1);
  // Out-of-range input is clamped, not undefined.
  EXPECT_EQ(merl_theta_h_index(std::nan("")), 0);
  EXPECT_EQ(merl_theta_d_index(std::nan("")), 0);
  EXPECT_EQ(merl_phi_d_index(std::nan("")), 0);
  EXPECT_EQ(merl_theta_h_index(1e300), 89);
  EXPECT_EQ(merl_theta_d_index(1e300), 89);
  EXPECT_EQ(merl_phi_d_index(-1e300), 0);
}

TEST(BrdfGeometry, SwappingDirectionsKeepsTheCell) {
  std::mt19937 rng(16);
  for (int n = 0; n < 2000; ++n) {
    const Eigen::Vector3d wi = random_upper(rng), wo = random_upper(rng);
    const Eigen::Vector2d i = spherical(wi), o = spherical(wo);
    const MerlCell a = merl_cell(StdAngles{i[0], i[1], o[0], o[1]});
    const MerlCell b = merl_cell(StdAngles{o[0], o[1], i[0], i[1]});
    EXPECT_EQ(merl_index(a), merl_index(b));
  }
}

// Closed form: with phi_h = 0, cos theta_i = cos h cos d - sin h sin d cos phi_d and cos theta_o the same with
// + sin h sin d cos phi_d; a cell is valid when both are positive.
TEST(BrdfGeometry, ValidCellsMatchTheClosedForm) {
  std::size_t valid = 0;
  for (std::size_t idx = 0; idx < kMerlCells; idx += 3) {
    const MerlCell c = merl_cell(idx);
    const HalfDiff h = merl_cell_centre(c);
    const double a = std::cos(h.theta_h) * std::cos(h.theta_d);
    const double b = std::sin(h.theta_h) * std::sin(h.theta_d) * std::abs(std::cos(h.phi_d));
    ASSERT_EQ(merl_cell_valid(c), a - b > 0) << idx;
    valid += a - b > 0;
  }
  EXPECT_GT(valid, 0u);
  EXPECT_LT(valid, kMerlCells / 3);
  EXPECT_TRUE(merl_cell_valid({0, 0, 0}));
  EXPECT_FALSE(merl_cell_valid({89, 89, 0}));
}

// Written apart from MerlCentres: wi = Ry(theta_h) d and wo = Ry(theta_h) d' with d' = d turned by pi about z.
TEST(BrdfGeometry, MerlCentresEqualEachCellsOwnCentreBitForBit) {
  for (int th = 0; th < kMerlThetaH; ++th)
    for (int td = 0; td < kMerlThetaD; ++td) {
      const MerlCentres row(th, td);
      for (int pd = 0; pd < kMerlPhiD; ++pd) {
        const MerlCell c{th, td, pd};
        const StdAngles a = std_angles(merl_cell_centre(c)), b = row.std_angles(pd);
        ASSERT_TRUE(a.theta_i == b.theta_i && a.phi_i == b.phi_i && a.theta_o == b.theta_o && a.phi_o == b.phi_o)
            << th << " " << td << " " << pd;
        Eigen::Vector3d wi, wo;
        row.directions(pd, wi, wo);
        const HalfDiff h = merl_cell_centre(c);
        const double ch = std::cos(h.theta_h), sh = std::sin(h.theta_h);
        const Eigen::Vector3d d(std::sin(h.theta_d) * std::cos(h.phi_d), std::sin(h.theta_d) * std::sin(h.phi_d),
                                std::cos(h.theta_d));
        const Eigen::Vector3d ei(ch * d.x() + sh * d.z(), d.y(), -sh * d.x() + ch * d.z());
        const Eigen::Vector3d eo(-ch * d.x() + sh * d.z(), -d.y(), sh * d.x() + ch * d.z());
        ASSERT_LT((wi - ei).norm() + (wo - eo).norm(), 1e-14) << th << " " << td << " " << pd;
        ASSERT_EQ(merl_cell_valid(c), wi.z() > 0 && wo.z() > 0);
      }
    }
}

// The trilinear corners: a cell centre is its own cell with weight 1; halfway between two phi_d centres each gets
// 1/2, across the wrap at pi too; theta_h and theta_d clamp at their ends; a linear function of the index
// coordinates is reproduced exactly from the corners' own coordinates.
TEST(BrdfGeometry, TrilinearCornersOfCentresMidpointsAndEnds) {
  const auto weight_of = [](const MerlCorners& m, std::size_t cell) {
    double w = 0;
    for (std::size_t c = 0; c < 8; ++c) w += m.cell[c] == cell ? m.weight[c] : 0.0;
    return w;
  };
  for (const MerlCell c : {MerlCell{3, 40, 17}, MerlCell{0, 0, 0}, MerlCell{89, 89, 179}, MerlCell{45, 12, 90}})
    EXPECT_NEAR(weight_of(merl_trilinear(merl_cell_centre(c)), merl_index(c)), 1.0, 1e-12);
  HalfDiff h = merl_cell_centre({10, 20, 179});
  h.phi_d += 0.5 * pi / kMerlPhiD;  // halfway to phi_d cell 0, across the wrap
  const MerlCorners w = merl_trilinear(h);
  EXPECT_NEAR(weight_of(w, merl_index({10, 20, 179})), 0.5, 1e-9);
  EXPECT_NEAR(weight_of(w, merl_index({10, 20, 0})), 0.5, 1e-9);
  h = merl_cell_centre({10, 20, 5});
  h.theta_d = 0;  // below theta_d row 0's centre: clamped to it
  EXPECT_NEAR(weight_of(merl_trilinear(h), merl_index({10, 0, 5})), 1.0, 1e-12);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 200; ++i) {
    const HalfDiff q{u(rng) * 1.5, 0.0, u(rng) * 1.5, u(rng) * 3.0 + 0.02};
    const MerlCorners m = merl_trilinear(q);
    double sum = 0, f = 0;
    for (std::size_t c = 0; c < 8; ++c) {
      const MerlCell k = merl_cell(m.cell[c]);
      sum += m.weight[c];
      f += m.weight[c] * (2.0 * k.theta_h - 3.0 * k.theta_d + 0.5 * k.phi_d);
    }
    const double x = 90 * std::sqrt(q.theta_h / (pi / 2)) - 0.5, y = 90 * q.theta_d / (pi / 2) - 0.5,
                 z = 180 * q.phi_d / pi - 0.5;
    ASSERT_NEAR(sum, 1.0, 1e-12);
    if (x > 0 && x < 89 && y > 0 && y < 89 && z > 0 && z < 179) {
      ASSERT_NEAR(f, 2.0 * x - 3.0 * y + 0.5 * z, 1e-9) << i;
    }
  }
}

}  // namespace
}  // namespace specula::brdf
