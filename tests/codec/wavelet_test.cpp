#include "specula/codec/wavelet.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace specula::codec::wavelet {
namespace {

std::vector<float> random_values(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0, 1);
  std::vector<float> v(n);
  for (auto& x : v) x = d(rng);
  return v;
}

TEST(Wavelet, ALineOfAnyLengthComesBack) {
  for (const std::size_t n : {2u, 3u, 4u, 5u, 12u, 23u, 45u, 90u}) {
    const auto x = random_values(n, unsigned(n));
    auto y = x;
    std::vector<float> scratch(n);
    forward_line(y, scratch);
    inverse_line(y, scratch);
    for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR(y[i], x[i], 1e-5) << n << " " << i;
  }
}

// The 9/7 high-pass has four vanishing moments, and symmetric extension keeps a constant constant: a constant line
// has no detail at all, and a cubic none away from the ends.
TEST(Wavelet, PolynomialsHaveNoDetail) {
  const std::size_t n = 90, lows = 45;
  std::vector<float> c(n, 3.5f), scratch(n);
  forward_line(c, scratch);
  for (std::size_t i = lows; i < n; ++i) EXPECT_NEAR(c[i], 0, 1e-5) << i;
  std::vector<float> p(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = double(i) / double(n);
    p[i] = float(1 + 2 * t - 3 * t * t + 0.5 * t * t * t);
  }
  forward_line(p, scratch);
  for (std::size_t i = lows + 3; i < n - 3; ++i) EXPECT_NEAR(p[i], 0, 2e-5) << i;
}

TEST(Wavelet, ACubeComesBackAtEveryLevelCount) {
  for (int levels = 0; levels <= 4; ++levels) {
    const CubeLayout layout{{18, 11, 30}, levels};
    const auto x = random_values(18 * 11 * 30, unsigned(levels));
    auto y = x;
    forward_cube(y, layout);
    if (levels > 0) {
      EXPECT_GT(std::abs(y[5] - x[5]) + std::abs(y[300] - x[300]), 1e-3);
    }
    inverse_cube(y, layout);
    for (std::size_t i = 0; i < x.size(); ++i) ASSERT_NEAR(y[i], x[i], 1e-4) << levels << " " << i;
  }
}

// Subband ranges tile the cube exactly once.
TEST(Wavelet, SubbandsTileTheCube) {
  const CubeLayout c{{90, 90, 90}, 4};
  std::vector<int> hits(90 * 90 * 90, 0);
  auto mark = [&](int l, int o) {
    const auto r0 = c.range(l, o, 0), r1 = c.range(l, o, 1), r2 = c.range(l, o, 2);
    for (std::size_t i = r0[0]; i < r0[1]; ++i)
      for (std::size_t j = r1[0]; j < r1[1]; ++j)
        for (std::size_t k = r2[0]; k < r2[1]; ++k) ++hits[(i * 90 + j) * 90 + k];
  };
  mark(4, 0);
  for (int l = 0; l < 4; ++l)
    for (int o = 1; o < 8; ++o) mark(l, o);
  for (const int h : hits) ASSERT_EQ(h, 1);
  EXPECT_EQ(c.low(4)[0], 6u);  // 90 -> 45 -> 23 -> 12 -> 6
}

// synthesis_norm is what an error in a subband costs: checked against the norm of an inverse-transformed unit
// coefficient placed off the middle of the same subband.
TEST(Wavelet, SynthesisNormsAreTheEnergyOfAUnitCoefficient) {
  const CubeLayout c{{90, 90, 90}, 3};
  for (const auto& [l, o] : {std::pair{0, 1}, std::pair{1, 5}, std::pair{2, 7}, std::pair{3, 0}}) {
    std::vector<float> x(90 * 90 * 90, 0.0f);
    auto mid = [&](int axis) { return (c.range(l, o, axis)[0] + c.range(l, o, axis)[1]) / 2; };
    x[((mid(0) + 1) * 90 + mid(1) - 1) * 90 + mid(2)] = 1;
    inverse_cube(x, c);
    double sq = 0;
    for (const float v : x) sq += double(v) * v;
    EXPECT_NEAR(std::sqrt(sq), c.synthesis_norm(l, o), 0.05 * c.synthesis_norm(l, o)) << l << " " << o;
  }
}

}  // namespace
}  // namespace specula::codec::wavelet
