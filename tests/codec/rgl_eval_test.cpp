// The RGL evaluator and its warp against a brute-force evaluation from the format's definitions, written here
// separately: the sample point is (F_x(x | y), F_y(y)) of the bilinear vndf density integrated numerically, the value
// a bilinear lookup of the stored table, times D / (4 sigma cos theta_o).
#include "specula/codec/rgl_eval.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "specula/codec/rgl_warp.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Vector3d brdf_direction(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Bilinear interpolation of a w x h node table (row-major, y rows) at (x, y) in [0, 1]^2.
double bilinear(const float* t, std::size_t w, std::size_t h, double x, double y) {
  const double fx = x * double(w - 1), fy = y * double(h - 1);
  const std::size_t ix = std::min(std::size_t(fx), w - 2), iy = std::min(std::size_t(fy), h - 2);
  const double ax = fx - double(ix), ay = fy - double(iy);
  auto v = [&](std::size_t i, std::size_t j) { return double(t[j * w + i]); };
  return (1 - ay) * ((1 - ax) * v(ix, iy) + ax * v(ix + 1, iy)) +
         ay * ((1 - ax) * v(ix, iy + 1) + ax * v(ix + 1, iy + 1));
}

// (F_x(x | y), F_y(y)) of the density bilinear(t) by midpoint sums.
Eigen::Vector2d brute_cdf(const float* t, std::size_t w, std::size_t h, double x, double y) {
  constexpr int n = 1000;
  auto row_integral = [&](double yy, double upto) {
    double s = 0;
    for (int k = 0; k < n; ++k) s += bilinear(t, w, h, (k + 0.5) / n * upto, yy) * upto / n;
    return s;
  };
  double total = 0;
  for (int k = 0; k < n; ++k) total += row_integral((k + 0.5) / n, 1.0);
  // Whole steps below y, then the partial one by the midpoint of what remains.
  const int full = int(std::floor(y * n));
  double below = 0;
  for (int k = 0; k < full; ++k) below += row_integral((k + 0.5) / n, 1.0);
  const double rest = y * n - full;
  if (rest > 0) below += row_integral((full + 0.5 * rest) / n, 1.0) * rest;
  return {row_integral(y, x) / row_integral(y, 1.0), below / total};
}

RglBsdf hand_made() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(0.2f, 1.0f), any(-0.05f, 1.0f);
  RglBsdf b;
  b.description = "hand-made";
  b.theta_i = {0.0f, 0.6f, 1.2f};
  b.ndf_width = 7;
  b.sigma_width = 5;
  for (int i = 0; i < 14; ++i) b.ndf.push_back(pos(rng) * 3);
  for (int i = 0; i < 10; ++i) b.sigma.push_back(pos(rng));
  b.vndf_width = 6;
  b.vndf_height = 5;
  for (int i = 0; i < 3 * 30; ++i) b.vndf.push_back(pos(rng));
  b.resolution = 4;
  b.rgb = true;
  for (int i = 0; i < 3 * 3 * 16; ++i) b.values.push_back(any(rng));
  b.luminance.assign(3 * 16, 1.0f);
  b.valid.assign(6, 0xff);
  return b;
}

double brute_f(const RglBsdf& b, std::size_t t, std::size_t c, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const Eigen::Vector3d m = (wi + wo).normalized();
  const double theta_m = std::acos(m.z()), phi_m = std::atan2(m.y(), m.x()), phi_i = std::atan2(wi.y(), wi.x());
  const double u = std::sqrt(theta_m / (kPi / 2));
  double v = (phi_m - phi_i + kPi) / (2 * kPi);
  v -= std::floor(v);
  const Eigen::Vector2d s =
      brute_cdf(b.vndf.data() + t * b.vndf_width * b.vndf_height, b.vndf_width, b.vndf_height, u, v);
  const std::size_t r = b.resolution;
  const double stored = bilinear(b.values.data() + (t * 3 + c) * r * r, r, r, s.x(), s.y());
  const double d = bilinear(b.ndf.data(), b.ndf_width, 2, u, v);
  const double sigma =
      bilinear(b.sigma.data(), b.sigma_width, 2, std::sqrt(std::acos(wi.z()) / (kPi / 2)), (phi_i + kPi) / (2 * kPi));
  return std::max(0.0, stored) * d / (4 * sigma * wo.z());
}

TEST(RglEval, MatchesABruteForceEvaluationAtTheTabulatedElevations) {
  const RglBsdf b = hand_made();
  const RglEvaluator e(b);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  int checked = 0;
  for (std::size_t t = 0; t < 3; ++t)
    for (int k = 0; k < 6; ++k) {
      const double phi_i = 2 * kPi * unit(rng);
      const Eigen::Vector3d wi(std::sin(b.theta_i[t]) * std::cos(phi_i), std::sin(b.theta_i[t]) * std::sin(phi_i),
                               std::cos(b.theta_i[t]));
      const double to = std::acos(0.05 + 0.95 * unit(rng)), po = 2 * kPi * unit(rng);
      const Eigen::Vector3d wo(std::sin(to) * std::cos(po), std::sin(to) * std::sin(po), std::cos(to));
      std::vector<double> f(3);
      e.eval(wi, wo, f);
      for (std::size_t c = 0; c < 3; ++c) {
        const double want = brute_f(b, t, c, wi, wo);
        EXPECT_NEAR(f[c], want, 2e-4 * std::max(1.0, want)) << "theta_i " << b.theta_i[t] << " channel " << c;
        ++checked;
      }
    }
  EXPECT_EQ(checked, 54);
}

TEST(RglEval, TheStencilIsEvalAsALinearMapOfTheStoredValues) {
  const RglBsdf b = hand_made();
  const RglEvaluator e(b);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> theta(0.05, 1.45), phi(-kPi, kPi);
  const std::size_t r2 = b.resolution * b.resolution;
  for (int k = 0; k < 40; ++k) {
    const Eigen::Vector3d wi = brdf_direction(theta(rng), phi(rng)), wo = brdf_direction(theta(rng), phi(rng));
    std::vector<double> f(3);
    e.eval(wi, wo, f);
    const RglStencil st = e.stencil(wi, wo);
    ASSERT_GE(st.n, 4);
    for (std::size_t c = 0; c < 3; ++c) {
      double sum = 0;
      for (int q = 0; q < st.n; ++q)
        sum += st.weight[std::size_t(q)] * b.values[(st.theta[std::size_t(q)] * 3 + c) * r2 + st.node[std::size_t(q)]];
      EXPECT_NEAR(std::max(sum, 0.0), f[c], 1e-9 * std::max(1.0, f[c])) << k << " " << c;
    }
  }
  EXPECT_EQ(e.stencil(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, -0.1).normalized()).n, 0);
}

TEST(RglEval, BelowTheHorizonIsZero) {
  const RglEvaluator e(hand_made());
  std::vector<double> f(3, 1.0);
  e.eval(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, -0.1).normalized(), f);
  EXPECT_EQ(f, std::vector<double>(3, 0.0));
}

TEST(RglWarp, SampleAndInvertAreInversesAndInvertIsTheCdf) {
  const RglBsdf b = hand_made();
  const Warp2D w(b.vndf, b.vndf_width, b.vndf_height, {{0.0f}, b.theta_i}, true);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.01, 0.99);
  for (int k = 0; k < 20; ++k) {
    const double x = unit(rng), y = unit(rng), theta = 1.3 * unit(rng);
    const double p[2] = {0, theta};
    const WarpPoint s = w.sample(x, y, p);
    const WarpPoint back = w.invert(s.x, s.y, p);
    EXPECT_NEAR(back.x, x, 1e-5);
    EXPECT_NEAR(back.y, y, 1e-5);
    EXPECT_NEAR(back.pdf, s.pdf, 1e-4 * s.pdf);
    EXPECT_NEAR(w.eval(s.x, s.y, p), s.pdf, 1e-4 * s.pdf);
  }
  // At a tabulated elevation, invert is the CDF pair of the bilinear density.
  for (int k = 0; k < 5; ++k) {
    const double x = unit(rng), y = unit(rng), p[2] = {0, double(b.theta_i[1])};
    const WarpPoint inv = w.invert(x, y, p);
    const Eigen::Vector2d want = brute_cdf(b.vndf.data() + 30, 6, 5, x, y);
    EXPECT_NEAR(inv.x, want.x(), 1e-5);
    EXPECT_NEAR(inv.y, want.y(), 1e-5);
  }
}

TEST(RglWarp, NonDensityTablesInterpolateAsStored) {
  const float t[] = {1, 2, 3, 4, 5, 6};  // 3 wide, 2 high
  const Warp2D w(t, 3, 2, {}, false);
  EXPECT_DOUBLE_EQ(w.eval(0, 0, {}), 1);
  EXPECT_DOUBLE_EQ(w.eval(1, 1, {}), 6);
  EXPECT_DOUBLE_EQ(w.eval(0.25, 0.5, {}), 0.5 * (1.5 + 4.5));
}

TEST(RglWarp, TheStencilIsWhatEvalBlends) {
  std::vector<float> t(3 * 4 * 6);
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = float((i * 29) % 13) - 3.5f;
  const Warp2D w(t, 3, 2, {{0.0f}, {0.0f, 0.5f, 1.5f}, {0.0f, 1.0f, 2.0f, 3.0f}}, false);
  for (const double theta : {0.0, 0.3, 1.0, 1.5, 2.0})
    for (const double c : {0.0, 1.0, 2.5}) {
      const double p[3] = {0, theta, c};
      for (const std::size_t dims : {2u, 3u}) {
        const WarpStencil s = w.stencil(0.7, 0.2, p, dims);
        double sum = 0;
        for (int k = 0; k < s.n; ++k) sum += s.weight[std::size_t(k)] * t[s.index[std::size_t(k)]];
        const double q[3] = {0, theta, dims == 3 ? c : 0.0};  // parameters past dims at their first value
        EXPECT_NEAR(sum, w.eval(0.7, 0.2, q), 1e-12) << theta << " " << c << " " << dims;
      }
    }
  const float d[] = {1, 2, 3, 4};
  EXPECT_THROW(Warp2D(d, 2, 2, {}, true).stencil(0, 0, {}, 0), UsageError);
}

TEST(RglWarp, AllChannelsAtOnceAreEachChannelInTurn) {
  // 3 elevations x 4 channels of 3 x 2 tables: eval_last at a point between elevations against eval per channel.
  std::vector<float> t(3 * 4 * 6);
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = float((i * 37) % 11) - 2.5f;
  const Warp2D w(t, 3, 2, {{0.0f}, {0.0f, 0.5f, 1.5f}, {0.0f, 1.0f, 2.0f, 3.0f}}, false);
  for (const double theta : {0.0, 0.3, 1.0, 1.5}) {
    std::vector<double> all(4);
    const double p[2] = {0, theta};
    w.eval_last(0.3, 0.8, p, all);
    for (std::size_t c = 0; c < 4; ++c) {
      const double q[3] = {0, theta, double(c)};
      EXPECT_NEAR(all[c], w.eval(0.3, 0.8, q), 1e-12) << theta << " " << c;
    }
  }
  std::vector<double> wrong(3);
  EXPECT_THROW(w.eval_last(0, 0, {}, wrong), UsageError);
}

}  // namespace
}  // namespace specula::codec
