#include "specula/core/brdf_mapping.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "specula/core/error.h"

namespace specula::brdf {
namespace {

using std::numbers::pi;

StdAngles random_angles(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  return {t(rng), p(rng), t(rng), p(rng)};
}

constexpr Mapping kAll[] = {Mapping::standard, Mapping::marschner, Mapping::halfdiff};

TEST(Mapping, IsotropyTurningAndMirroringBothAzimuthsChangesNothing) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 300; ++i) {
    const StdAngles a = random_angles(rng);
    const double turn = 0.37 * i - 40;
    const StdAngles turned{a.theta_i, a.phi_i + turn, a.theta_o, a.phi_o + turn};
    const StdAngles mirrored{a.theta_i, -a.phi_i, a.theta_o, -a.phi_o};
    for (const Mapping m : kAll) {
      EXPECT_LT((map_angles(m, turned) - map_angles(m, a)).norm(), 1e-9) << mapping_name(m);
      EXPECT_LT((map_angles(m, mirrored) - map_angles(m, a)).norm(), 1e-9) << mapping_name(m);
    }
    // Eq 5.6: phi_d and phi_d + 2 pi j are the same configuration.
    const IsoAngles iso = iso_angles(a);
    EXPECT_NEAR(iso.phi_d, phi_difference(a.phi_i + 2 * pi * (i % 5 - 2), a.phi_o), 1e-9);
    EXPECT_GE(iso.phi_d, 0);
    EXPECT_LE(iso.phi_d, pi);
  }
}

TEST(Mapping, MarschnerAndHalfDiffIdentifyReciprocalConfigurationsAndStandardDoesNot) {
  std::mt19937_64 rng(2);
  for (int i = 0; i < 300; ++i) {
    const StdAngles a = random_angles(rng);
    const StdAngles swapped{a.theta_o, a.phi_o, a.theta_i, a.phi_i};  // eq 5.7
    // Eq 5.8 written out independently.
    const double pd = std::acos(std::cos(a.phi_o - a.phi_i));
    const Eigen::Vector3d mm(std::sin(a.theta_i) * std::sin(a.theta_o), pd / pi,
                             std::cos(a.theta_i) * std::cos(a.theta_o));
    EXPECT_LT((map_angles(Mapping::marschner, a) - mm).norm(), 1e-9);
    EXPECT_LT((map_angles(Mapping::marschner, swapped) - map_angles(Mapping::marschner, a)).norm(), 1e-12);
    EXPECT_LT((map_angles(Mapping::halfdiff, swapped) - map_angles(Mapping::halfdiff, a)).norm(), 1e-9);
    EXPECT_TRUE(mapping_is_reciprocal(Mapping::marschner));
    EXPECT_TRUE(mapping_is_reciprocal(Mapping::halfdiff));
    EXPECT_FALSE(mapping_is_reciprocal(Mapping::standard));
    if (std::abs(a.theta_i - a.theta_o) > 1e-3) {
      EXPECT_GT((map_angles(Mapping::standard, swapped) - map_angles(Mapping::standard, a)).norm(), 1e-4);
    }
  }
}

TEST(Mapping, HalfDiffPointIsTheMerlHalfAngleAndDifferenceAngle) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 100; ++i) {
    const StdAngles a = random_angles(rng);
    const brdf::HalfDiff h = brdf::half_diff(a);
    const Eigen::Vector3d p = map_angles(Mapping::halfdiff, a);
    EXPECT_NEAR(p[0], h.theta_h, 1e-9);
    EXPECT_NEAR(p[1], h.theta_d, 1e-9);
    // phi_d folded by mirroring and reciprocity: |sin| and |cos| of the MERL phi_d are kept.
    EXPECT_NEAR(std::sin(p[2]), std::abs(std::sin(h.phi_d)), 1e-9);
    EXPECT_NEAR(std::cos(p[2]), std::abs(std::cos(h.phi_d)), 1e-9);
  }
}

TEST(Mapping, UnmapGivesAnEquivalentConfiguration) {
  std::mt19937_64 rng(4);
  for (int i = 0; i < 300; ++i) {
    const IsoAngles a = iso_angles(random_angles(rng));
    for (const Mapping m : kAll) {
      const IsoAngles back = unmap(m, map_angles(m, a));
      EXPECT_LT(config_distance(a, back, mapping_is_reciprocal(m)), 1e-6) << mapping_name(m);
      EXPECT_LT((map_angles(m, back) - map_angles(m, a)).norm(), 1e-6) << mapping_name(m);
    }
  }
  EXPECT_THROW(parse_mapping("polar"), UsageError);
  EXPECT_EQ(parse_mapping("halfdiff"), Mapping::halfdiff);
}

// Brute force: turn b's directions about the normal in small steps (and mirror, and swap them) and keep the
// least sqrt(|wi_a - wi_b|^2 + |wo_a - wo_b|^2).
double brute_distance(const IsoAngles& a, const IsoAngles& b, bool reciprocal) {
  const Eigen::Vector3d ai = brdf::direction(a.theta_i, 0.3), ao = brdf::direction(a.theta_o, 0.3 + a.phi_d);
  double best = 1e9;
  for (int swap = 0; swap < (reciprocal ? 2 : 1); ++swap)
    for (const double sign : {1.0, -1.0})
      for (int s = 0; s < 20000; ++s) {
        const double psi = 2 * pi * s / 20000;
        const double ti = swap ? b.theta_o : b.theta_i, to = swap ? b.theta_i : b.theta_o;
        const Eigen::Vector3d bi = brdf::direction(ti, psi), bo = brdf::direction(to, psi + sign * b.phi_d);
        best = std::min(best, std::sqrt((ai - bi).squaredNorm() + (ao - bo).squaredNorm()));
      }
  return best;
}

TEST(Mapping, ConfigDistanceIsTheLeastDistanceOverTurnsMirrorsAndSwaps) {
  std::mt19937_64 rng(5);
  for (int i = 0; i < 40; ++i) {
    const IsoAngles a = iso_angles(random_angles(rng)), b = iso_angles(random_angles(rng));
    for (const bool rec : {false, true}) EXPECT_NEAR(config_distance(a, b, rec), brute_distance(a, b, rec), 2e-4);
  }
  // Closed forms: theta_i alone differing by d is a chord 2 sin(d / 2); at theta_i = 0 phi_d means nothing;
  // the swapped configuration is at distance 0 only when reciprocity is allowed.
  EXPECT_NEAR(config_distance({0.4, 0.7, 1.0}, {0.5, 0.7, 1.0}, false), 2 * std::sin(0.05), 1e-9);
  EXPECT_NEAR(config_distance({0.0, 0.7, 0.3}, {0.0, 0.7, 2.9}, false), 0, 1e-7);
  EXPECT_GT(config_distance({0.2, 0.7, 1.0}, {0.7, 0.2, 1.0}, false), 0.4);
  EXPECT_NEAR(config_distance({0.2, 0.7, 1.0}, {0.7, 0.2, 1.0}, true), 0, 1e-7);
}

// The bound against config_distance itself, on far pairs, near pairs (where a bound is tightest) and pairs beside
// the folds of phi_d (0, pi/2, pi) and the pole; and M_m's lack of one: a pair near the pole far apart in config
// space but close under M_m.
TEST(Mapping, ConfigDistanceIsBoundedByTheMappedDistance) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  double tightest[2] = {0, 0};
  for (int i = 0; i < 20000; ++i) {
    IsoAngles a = iso_angles(random_angles(rng)), b = a;
    const double scale = i % 3 == 0 ? 1.0 : i % 3 == 1 ? 1e-2 : 1e-5;
    b.theta_i = std::clamp(a.theta_i + scale * (u(rng) - 0.5), 0.0, pi / 2);
    b.theta_o = std::clamp(a.theta_o + scale * (u(rng) - 0.5), 0.0, pi / 2);
    b.phi_d = std::clamp(a.phi_d + scale * (u(rng) - 0.5), 0.0, pi);
    if (i % 7 == 0) a.phi_d = b.phi_d = std::array{0.0, pi / 2, pi}[std::size_t(i / 7 % 3)];
    if (i % 11 == 0) a.theta_i = 1e-4 * u(rng);
    for (const Mapping m : {Mapping::standard, Mapping::halfdiff}) {
      const double c = config_distance_bound(m), mapped = (map_angles(m, a) - map_angles(m, b)).norm();
      const double d = config_distance(a, b, mapping_is_reciprocal(m));
      // config_distance computes sqrt(4 - 2 (...)): about 1e-8 of rounding near 0 (finish allows 1e-5)
      ASSERT_LE(d, c * mapped * (1 + 1e-9) + 1e-7) << mapping_name(m) << " " << i;
      if (mapped > 1e-3)
        tightest[m == Mapping::halfdiff] = std::max(tightest[m == Mapping::halfdiff], d / (c * mapped));
    }
  }
  EXPECT_GT(tightest[0], 0.9);  // the bound is not loose where it is claimed
  EXPECT_GT(tightest[1], 0.3);
  EXPECT_EQ(config_distance_bound(Mapping::marschner), std::numeric_limits<double>::infinity());
  // (e, e, 0) and (0, 2 e, 0): about e^2 apart under M_m, about e in config space.
  const IsoAngles p{1e-3, 1e-3, 0.0}, q{0.0, 2e-3, 0.0};
  const double marschner = (map_angles(Mapping::marschner, p) - map_angles(Mapping::marschner, q)).norm();
  EXPECT_GT(config_distance(p, q, true), 500 * marschner);
}

}  // namespace
}  // namespace specula::brdf
