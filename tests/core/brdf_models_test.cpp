#include "specula/core/brdf_models.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "specula/core/error.h"

namespace specula::brdf {
namespace {

using std::numbers::pi;
constexpr double kRadPerDeg = pi / 180;

// Gauss-Legendre nodes and weights on [a, b] (Newton on P_n).
void gauss_legendre(int n, double a, double b, std::vector<double>& x, std::vector<double>& w) {
  for (int i = 0; i < n; ++i) {
    double z = std::cos(pi * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = 0;
      for (int k = 1; k <= n; ++k) {
        const double p2 = p1;
        p1 = p0;
        p0 = ((2 * k - 1) * z * p1 - (k - 1) * p2) / k;
      }
      dp = n * (z * p0 - p1) / (z * z - 1);
      const double dz = p0 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-15) break;
    }
    x.push_back(0.5 * (a + b) + 0.5 * (b - a) * z);
    w.push_back((b - a) / ((1 - z * z) * dp * dp));
  }
}

// Directional albedo (eq 2.3's integral) of band `band` for incidence wi, integrated over half vectors:
// wo = 2 (wi.h) h - wi, d(wo) = 4 (wi.h) d(h), so narrow lobes are resolved by refining theta_h near 0.
Eigen::VectorXd albedos_half(const SpectralModel& f, const Eigen::Vector3d& wi) {
  std::vector<double> x, w;
  const double edges[] = {0, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.2, pi / 2};
  for (std::size_t s = 0; s + 1 < std::size(edges); ++s) gauss_legendre(32, edges[s], edges[s + 1], x, w);
  const int nphi = 256;
  std::vector<double> v(f.bands());
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Eigen::Index(f.bands()));
  for (std::size_t i = 0; i < x.size(); ++i)
    for (int j = 0; j < nphi; ++j) {
      const Eigen::Vector3d h = direction(x[i], 2 * pi * j / nphi);
      const double c = wi.dot(h);
      if (c <= 0) continue;
      const Eigen::Vector3d wo = 2 * c * h - wi;
      if (wo.z() <= 0) continue;
      f.eval(wi, wo, v);
      sum += w[i] * std::sin(x[i]) * (2 * pi / nphi) * wo.z() * 4 * c *
             Eigen::Map<const Eigen::VectorXd>(v.data(), Eigen::Index(v.size()));
    }
  return sum;
}

double albedo_half(const SpectralModel& f, const Eigen::Vector3d& wi, std::size_t band) {
  return albedos_half(f, wi)[Eigen::Index(band)];
}

// The same integral over outgoing directions with Gauss-Legendre in cos(theta_o): exact for polynomials in cos.
double albedo_direct(const SpectralModel& f, const Eigen::Vector3d& wi, std::size_t band) {
  std::vector<double> mu, w;
  gauss_legendre(16, 0, 1, mu, w);
  std::vector<double> v(f.bands());
  double sum = 0;
  const int nphi = 64;
  for (std::size_t i = 0; i < mu.size(); ++i)
    for (int j = 0; j < nphi; ++j) {
      f.eval(wi, direction(std::acos(mu[i]), 2 * pi * j / nphi), v);
      sum += w[i] * (2 * pi / nphi) * v[band] * mu[i];
    }
  return sum;
}

// Fresnel from the amplitude coefficients in cosines (Hecht), independent of eq 5.11's sine/tangent form.
double fresnel_cos(double theta, double eta) {
  const double ci = std::cos(theta), st = std::sin(theta) / eta;
  const double ct = std::sqrt(1 - st * st);
  const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
  return 0.5 * (rs * rs + rp * rp);
}

WavelengthGrid grid3() { return WavelengthGrid({450, 550, 650}); }

TorranceSparrow ts(double m, Eigen::Vector3d eta, double rho_d = 0) {
  return TorranceSparrow(grid3(), Eigen::Vector3d::Constant(m), eta, Eigen::Vector3d::Constant(rho_d));
}

TEST(BrdfModels, FresnelMatchesTheCosineForm) {
  for (double eta : {1.2, 1.5, 2.4})
    for (double t = 0.5; t < 89.6; t += 1.0)
      EXPECT_NEAR(fresnel_dielectric(t * kRadPerDeg, eta), fresnel_cos(t * kRadPerDeg, eta), 1e-12);
  EXPECT_NEAR(fresnel_dielectric(0, 1.5), 0.04, 1e-15);
  EXPECT_NEAR(fresnel_dielectric(1e-9, 1.5), 0.04, 1e-12);
  EXPECT_NEAR(fresnel_dielectric(pi / 2 - 1e-9, 1.5), 1.0, 1e-6);
  EXPECT_EQ(fresnel_dielectric(60 * kRadPerDeg, 1 / 1.5), 1.0);  // beyond the critical angle asin(1/1.5) = 41.8 deg
}

TEST(BrdfModels, Reciprocity) {
  const WavelengthGrid g = grid3();
  const Lambertian lam(g, Eigen::Vector3d(0.2, 0.5, 0.8));
  const TorranceSparrow t(g, Eigen::Vector3d(0.1, 0.2, 0.4), Eigen::Vector3d(1.3, 1.5, 1.7),
                          Eigen::Vector3d(0.1, 0.2, 0.3));
  const Ward w(g, Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(0.5, 0.3, 0.1), Eigen::Vector3d(0.05, 0.1, 0.3));
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> a(3), b(3);
  for (const SpectralModel* m : std::initializer_list<const SpectralModel*>{&lam, &t, &w})
    for (int n = 0; n < 1000; ++n) {
      const Eigen::Vector3d wi = direction(std::acos(0.01 + 0.99 * u(rng)), 2 * pi * u(rng));
      const Eigen::Vector3d wo = direction(std::acos(0.01 + 0.99 * u(rng)), 2 * pi * u(rng));
      m->eval(wi, wo, a);
      m->eval(wo, wi, b);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], b[k], 1e-12 * std::max(1.0, std::abs(a[k])));
    }
}

TEST(BrdfModels, LambertianAlbedoIsRhoExactly) {
  const Lambertian lam(grid3(), Eigen::Vector3d(0.2, 0.5, 1.0));
  for (double ti : {0.0, 30.0, 75.0, 89.0}) {
    const Eigen::Vector3d wi = direction(ti * kRadPerDeg, 0.3);
    // Exact quadrature: only rounding remains.
    EXPECT_NEAR(albedo_direct(lam, wi, 0), 0.2, 1e-13);
    EXPECT_NEAR(albedo_direct(lam, wi, 1), 0.5, 1e-13);
    EXPECT_NEAR(albedo_direct(lam, wi, 2), 1.0, 1e-13);
  }
  std::vector<double> v(3);
  lam.eval(direction(0.1, 0), direction(pi / 2 + 0.01, 0), v);
  EXPECT_EQ(v[0], 0.0);  // below the horizon
}

// Hand-computed values of eq 5.11 at three configurations.
TEST(BrdfModels, TorranceSparrowKnownValues) {
  const double m = 0.2;
  const auto t = ts(m, Eigen::Vector3d(1.5, 1.5, 1.5));
  std::vector<double> v(3);
  // Mirror at 30 deg: theta_h = 0 so D = 1 / (4 m^2), G = 1, theta_d = 30 deg.
  t.eval(StdAngles{30 * kRadPerDeg, 0, 30 * kRadPerDeg, pi}, v);
  const double f_mirror = fresnel_cos(30 * kRadPerDeg, 1.5) / (4 * m * m * pi * std::pow(std::cos(30 * kRadPerDeg), 2));
  EXPECT_NEAR(v[1], f_mirror, 1e-12 * f_mirror);
  EXPECT_NEAR(fresnel_cos(30 * kRadPerDeg, 1.5), 0.041523, 1e-6);
  // Normal incidence, theta_o = 40 deg: theta_h = theta_d = 20 deg, G = min(1, 2, 2 cos 40) = 1.
  t.eval(StdAngles{0, 0, 40 * kRadPerDeg, 0}, v);
  const double c20 = std::cos(20 * kRadPerDeg), t20 = std::tan(20 * kRadPerDeg);
  const double f_off = std::exp(-t20 * t20 / (m * m)) / (4 * m * m * std::pow(c20, 4)) *
                       fresnel_cos(20 * kRadPerDeg, 1.5) / (pi * std::cos(40 * kRadPerDeg));
  EXPECT_NEAR(v[1], f_off, 1e-12 * f_off);
  // Both at 85 deg, 90 deg apart in azimuth: masking, G = 4 c^2 / (s^2 + 2 c^2) with c = cos 85, s = sin 85.
  t.eval(StdAngles{85 * kRadPerDeg, 0, 85 * kRadPerDeg, pi / 2}, v);
  const double c = std::cos(85 * kRadPerDeg), s = std::sin(85 * kRadPerDeg);
  const double norm = std::sqrt(2 * s * s + 4 * c * c);
  const double ch = 2 * c / norm, cd = (s * s + 2 * c * c) / norm;
  const double g = 4 * c * c / (s * s + 2 * c * c);
  ASSERT_LT(g, 1.0);
  const double d = std::exp(-(1 - ch * ch) / (ch * ch) / (m * m)) / (4 * m * m * std::pow(ch, 4));
  const double f_graze = d * g * fresnel_cos(std::acos(cd), 1.5) / (pi * c * c);
  EXPECT_NEAR(v[1], f_graze, 1e-10 * f_graze);
}

// Spectral eta: a higher index reflects more at normal incidence, ((eta - 1) / (eta + 1))^2 per band.
TEST(BrdfModels, TorranceSparrowSpectralEta) {
  const double m = 0.3;
  const auto t = ts(m, Eigen::Vector3d(1.3, 1.5, 2.0));
  std::vector<double> v(3);
  t.eval(StdAngles{0, 0, 0, 0}, v);
  for (int k = 0; k < 3; ++k) {
    const double eta = std::array{1.3, 1.5, 2.0}[std::size_t(k)];
    const double f0 = (eta - 1) * (eta - 1) / ((eta + 1) * (eta + 1));
    EXPECT_NEAR(v[std::size_t(k)], f0 / (4 * m * m * pi), 1e-12);
  }
}

TEST(BrdfModels, TorranceSparrowConservesEnergy) {
  // eta = 1e6 makes F = 1 everywhere: the bound is tightest.
  for (double m : {0.1, 0.3, 0.6}) {
    const auto t = ts(m, Eigen::Vector3d(1.5, 1e6, 3.0));
    for (double ti : {0.0, 30.0, 60.0, 80.0, 88.0}) {
      const Eigen::Vector3d wi = direction(ti * kRadPerDeg, 0.7);
      const Eigen::VectorXd a = albedos_half(t, wi);
      for (Eigen::Index b = 0; b < 3; ++b) {
        EXPECT_LE(a[b], 1.0) << "m " << m << " theta_i " << ti << " band " << b;
        EXPECT_GT(a[b], 0.0);
      }
      EXPECT_LT(a[0], a[1]);  // eta 1.5 reflects less than F = 1
    }
  }
  // Smooth and F = 1 at normal incidence: almost all the light comes back (shadowing is nil there).
  const auto mirror = ts(0.05, Eigen::Vector3d(1e6, 1e6, 1e6));
  EXPECT_NEAR(albedo_half(mirror, Eigen::Vector3d(0, 0, 1), 0), 1.0, 2e-3);
}

// Eq 5.12 at normal incidence reduces, with wo the mirror of wi about h (theta_o = 2 theta_h,
// d(wo) = 4 cos(theta_h) d(h)), to the one-dimensional integral
// (2 / alpha^2) int_0^{pi/4} exp(-tan^2 t / alpha^2) sqrt(cos 2t) cos t sin t dt.
double ward_normal_albedo_1d(double alpha) {
  const int n = 200000;
  const double hgrid = (pi / 4) / n;
  double s = 0;
  for (int i = 0; i <= n; ++i) {
    const double t = i * hgrid, tt = std::tan(t);
    const double y =
        std::exp(-tt * tt / (alpha * alpha)) * std::sqrt(std::max(0.0, std::cos(2 * t))) * std::cos(t) * std::sin(t);
    s += y * ((i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2));
  }
  return 2 / (alpha * alpha) * s * hgrid / 3;
}

TEST(BrdfModels, WardNormalisationAndEnergy) {
  const WavelengthGrid g = grid3();
  const Ward w(g, Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0.6, 0.3), Eigen::Vector3d(0.03, 0.08, 0.2));
  const Eigen::Vector3d n(0, 0, 1);
  const double rho[] = {1.0, 0.6, 0.3}, alpha[] = {0.03, 0.08, 0.2};
  const Eigen::VectorXd albedo = albedos_half(w, n);
  for (std::size_t b = 0; b < 3; ++b) {
    const double a = albedo[Eigen::Index(b)];
    EXPECT_NEAR(a, rho[b] * ward_normal_albedo_1d(alpha[b]), 1e-6) << b;
    EXPECT_LE(a, rho[b]);
  }
  // Small alpha: the normalisation is close to rho_s, the deficit shrinking as alpha^2 (about 3 alpha^2).
  const double deficit_small = 1.0 - albedo[0];
  EXPECT_GT(deficit_small, 0.0);
  EXPECT_LT(deficit_small, 3.5 * 0.03 * 0.03);
  EXPECT_LT(deficit_small / (0.03 * 0.03), (1.0 - ward_normal_albedo_1d(0.08)) / (0.08 * 0.08) * 1.1);
  for (double ti : {20.0, 45.0, 70.0}) EXPECT_LE(albedo_half(w, direction(ti * kRadPerDeg, 0), 0), 1.0) << ti;
  // Hand value at the mirror direction of 30 deg: rho_s / (4 pi alpha^2 cos 30).
  std::vector<double> v(3);
  w.eval(StdAngles{30 * kRadPerDeg, 0, 30 * kRadPerDeg, pi}, v);
  EXPECT_NEAR(v[1], 0.6 / (4 * pi * 0.08 * 0.08 * std::cos(30 * kRadPerDeg)), 1e-10);
  w.eval(StdAngles{0, 0, 40 * kRadPerDeg, 1.0}, v);
  const double t20 = std::tan(20 * kRadPerDeg);
  EXPECT_NEAR(v[2], 0.3 * std::exp(-t20 * t20 / 0.04) / (4 * pi * 0.04 * std::sqrt(std::cos(40 * kRadPerDeg))), 1e-12);
}

TEST(BrdfModels, ParametersAreChecked) {
  const WavelengthGrid g = grid3();
  EXPECT_THROW(Lambertian(g, Eigen::Vector2d(0.1, 0.2)), UsageError);
  EXPECT_THROW(Lambertian(g, Eigen::Vector3d(0.1, 1.2, 0.2)), UsageError);
  EXPECT_THROW(ts(0.0, Eigen::Vector3d(1.5, 1.5, 1.5)), UsageError);
  EXPECT_THROW(ts(0.1, Eigen::Vector3d(1.5, NAN, 1.5)), UsageError);
  EXPECT_THROW(Ward(g, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(), Eigen::Vector3d(0.1, -0.1, 0.1)), UsageError);
  try {
    Lambertian(g, Eigen::Vector3d(0.1, 1.2, 0.2));
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("550 nm is 1.2"), std::string::npos) << e.what();
  }
}

TEST(BrdfModels, GridHoldsCellCentreValuesAndMarksInvalidCells) {
  const WavelengthGrid g({500, 600});
  const Ward w(g, Eigen::Vector2d(0.2, 0.4), Eigen::Vector2d(0.3, 0.1), Eigen::Vector2d(0.1, 0.2));
  std::vector<float> grid(2 * kMerlCells);
  evaluate_grid(w, grid);
  std::size_t invalid = 0;
  std::vector<double> v(2);
  for (std::size_t idx = 0; idx < kMerlCells; ++idx) {
    const MerlCell c = merl_cell(idx);
    if (!merl_cell_valid(c)) {
      ++invalid;
      ASSERT_EQ(grid[idx], -1.0f);
      ASSERT_EQ(grid[kMerlCells + idx], -1.0f);
      continue;
    }
    if (idx % 97) continue;
    w.eval(std_angles(merl_cell_centre(c)), v);
    ASSERT_NEAR(grid[idx], v[0], 1e-6 * v[0]);
    ASSERT_NEAR(grid[kMerlCells + idx], v[1], 1e-6 * v[1]);
  }
  EXPECT_GT(invalid, 0u);
  EXPECT_THROW(evaluate_grid(w, std::span<float>(grid.data(), kMerlCells)), UsageError);

  const double angles[8] = {0.3, 0.1, 0.5, 2.0, 1.2, -1.0, 0.2, 0.0};
  float values[4];
  evaluate_at(w, angles, values);
  w.eval(StdAngles{1.2, -1.0, 0.2, 0.0}, v);
  EXPECT_FLOAT_EQ(values[2], float(v[0]));
  EXPECT_FLOAT_EQ(values[3], float(v[1]));
  EXPECT_THROW(evaluate_at(w, angles, std::span<float>(values, 3)), UsageError);
}

}  // namespace
}  // namespace specula::brdf
