// The approximating weightings of core/brdf_resample.h (wendland, loess) against independent answers: the kernel in
// closed form, exact reproduction of linear functions by the local linear fit, and both against a brute-force
// estimate written here (every sample's distance, the fit solved per band by QR, no code shared with the library).
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "specula/core/brdf_resample.h"
#include "specula/core/error.h"

namespace specula::brdf {
namespace {

using std::numbers::pi;

struct Samples {
  std::vector<double> angles;
  std::vector<float> values;
  std::vector<Eigen::Vector3d> mapped;  // M_s: (theta_i, theta_o, phi_d)
};

StdAngles random_angles(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  return {t(rng), p(rng), t(rng), p(rng)};
}

Eigen::Vector3d standard_point(const StdAngles& a) {
  double pd = std::abs(a.phi_o - a.phi_i);
  pd = std::fmod(pd, 2 * pi);
  if (pd > pi) pd = 2 * pi - pd;
  return {a.theta_i, a.theta_o, pd};
}

// n random samples of two bands: a linear function of the mapped point, and a smooth curved one.
Samples samples(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Samples s;
  for (std::size_t i = 0; i < n; ++i) {
    const StdAngles a = random_angles(rng);
    const Eigen::Vector3d p = standard_point(a);
    s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    s.values.push_back(float(2 + 0.5 * p[0] - 0.75 * p[1] + 0.25 * p[2]));
    s.values.push_back(float(1 + std::cos(2 * p[0]) * std::cos(p[1]) + 0.1 * std::cos(p[2])));
    s.mapped.push_back(p);
  }
  return s;
}

// Wendland-weighted mean or local linear fit of band q at p from the k nearest of all samples, R the (k+1)-th
// nearest distance: the fit a + b . (x - p) by weighted least squares, solved by QR of the sqrt(w)-scaled design.
double brute(const Samples& s, const Eigen::Vector3d& p, std::size_t k, std::size_t q, bool linear) {
  std::vector<std::pair<double, std::size_t>> d;
  for (std::size_t i = 0; i < s.mapped.size(); ++i) d.emplace_back((s.mapped[i] - p).norm(), i);
  std::sort(d.begin(), d.end());
  const double reach = d[k].first;
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(Eigen::Index(k), linear ? 4 : 1);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(Eigen::Index(k));
  for (std::size_t j = 0; j < k; ++j) {
    const double r = d[j].first / reach, w = std::sqrt(std::pow(1 - r, 4) * (4 * r + 1));
    const auto row = Eigen::Index(j);
    x(row, 0) = w;
    if (linear) x.block<1, 3>(row, 1) = w * (s.mapped[d[j].second] - p).transpose();
    y[row] = w * s.values[2 * d[j].second + q];
  }
  return x.colPivHouseholderQr().solve(y)[0];
}

TEST(SmoothingWeights, WendlandKernelInClosedForm) {
  std::vector<float> w(3);
  // R = 4: (1 - r)^4 (4 r + 1) at r = 1/4, 1/2, 3/4 is 81/128, 24/128, 2/128, over their sum 107/128.
  neighbour_weights(Weights::wendland, 1, std::vector<float>{1, 4, 9}, w, 16);
  EXPECT_FLOAT_EQ(w[0], 81.0f / 107);
  EXPECT_FLOAT_EQ(w[1], 24.0f / 107);
  EXPECT_FLOAT_EQ(w[2], 2.0f / 107);
  // A sample at distance 0 keeps the kernel's finite weight 1: the estimate smooths, it does not interpolate.
  neighbour_weights(Weights::wendland, 1, std::vector<float>{0, 4, 9}, w, 16);
  EXPECT_FLOAT_EQ(w[0], 128.0f / (128 + 24 + 2));
  // No (k+1)-th sample: R is 1.5 times the farthest neighbour's distance, 4.5 here.
  neighbour_weights(Weights::wendland, 1, std::vector<float>{1, 4, 9}, w);
  auto phi = [](double r) { return std::pow(1 - r, 4) * (4 * r + 1); };
  const double sum = phi(1 / 4.5) + phi(2 / 4.5) + phi(3 / 4.5);
  EXPECT_FLOAT_EQ(w[2], float(phi(3 / 4.5) / sum));
  // Every neighbour at the reach: the mean.
  neighbour_weights(Weights::wendland, 1, std::vector<float>{4, 4, 4}, w, 4);
  for (const float x : w) EXPECT_FLOAT_EQ(x, 1.0f / 3);
  EXPECT_THROW(neighbour_weights(Weights::loess, 1, std::vector<float>{1, 4, 9}, w, 16), UsageError);
}

TEST(SmoothingWeights, LoessReproducesALinearFunctionWhereTheMeanCannot) {
  const Samples s = samples(1500, 3);
  const Resampler loess(s.angles, s.values, 2, {.k = 16, .weights = Weights::loess, .max_gap = 10});
  const Resampler wendland(s.angles, s.values, 2, {.k = 16, .weights = Weights::wendland, .max_gap = 10});
  std::mt19937_64 rng(4);
  std::vector<float> out(2);
  double worst_loess = 0, worst_wendland = 0;
  for (int i = 0; i < 200; ++i) {
    const StdAngles at = random_angles(rng);
    const Eigen::Vector3d p = standard_point(at);
    const double truth = 2 + 0.5 * p[0] - 0.75 * p[1] + 0.25 * p[2];
    ASSERT_TRUE(loess.predict(at, out));
    worst_loess = std::max(worst_loess, std::abs(out[0] - truth));
    ASSERT_TRUE(wendland.predict(at, out));
    worst_wendland = std::max(worst_wendland, std::abs(out[0] - truth));
  }
  EXPECT_LT(worst_loess, 1e-4);
  EXPECT_GT(worst_wendland, 1e-2);  // a weighted mean is biased wherever the neighbours are lopsided
}

TEST(SmoothingWeights, PredictEqualsABruteForceEstimateAndTheGrid) {
  const Samples s = samples(1500, 7);
  const std::size_t k = 12;
  std::mt19937_64 rng(8);
  std::vector<float> out(2);
  for (const Weights w : {Weights::wendland, Weights::loess}) {
    const Resampler r(s.angles, s.values, 2, {.k = k, .weights = w, .max_gap = 10});
    for (int i = 0; i < 40; ++i) {
      const StdAngles at = random_angles(rng);
      ASSERT_TRUE(r.predict(at, out));
      for (std::size_t q = 0; q < 2; ++q) {
        const double b = std::max(0.0, brute(s, standard_point(at), k, q, w == Weights::loess));
        EXPECT_NEAR(out[q], b, 1e-4 * std::max(1.0, std::abs(b))) << weights_name(w) << " " << i << " " << q;
      }
    }
    if (w != Weights::loess) continue;
    // The streamed grid holds what predict gives at the cell centres, negative fits clamped to 0 in both.
    std::vector<float> grid(2 * kMerlCells);
    r.fill_grid(grid);
    for (std::size_t c = 0; c < kMerlCells; c += 4099) {
      const brdf::MerlCell cell = brdf::merl_cell(c);
      if (!brdf::merl_cell_valid(cell)) continue;
      ASSERT_TRUE(r.predict(brdf::std_angles(brdf::merl_cell_centre(cell)), out));
      ASSERT_EQ(grid[c], out[0]) << c;
      ASSERT_EQ(grid[kMerlCells + c], out[1]) << c;
    }
  }
}

}  // namespace
}  // namespace specula::brdf
