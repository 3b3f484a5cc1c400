// resample_density: a vndf table made coarser keeps the warp the renderers build from it (Warp2D::invert of the
// original table, the map from directions to the sample square that the stored values are tabulated on), where
// point samples at the coarse nodes lose a sharp peak's mass between them.
#include "specula/codec/rgl_warp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "specula/core/error.h"

namespace specula::codec {
namespace {

constexpr double kPi = std::numbers::pi;

// Two slices (two incident directions) of a glossy material's visible-normal density on the square: a peak of width
// 0.06 in x = u (theta = u^2 pi / 2) on a floor, times the square's Jacobian, and in y = v a clipped cosine of phi.
std::vector<float> glossy_density(std::size_t w, std::size_t h) {
  std::vector<float> t;
  for (double tilt : {0.2, 0.9})
    for (std::size_t j = 0; j < h; ++j)
      for (std::size_t i = 0; i < w; ++i) {
        const double u = double(i) / double(w - 1), phi = 2 * kPi * double(j) / double(h - 1) - kPi;
        const double theta = u * u * kPi / 2, d = 1000 * std::exp(-(u / 0.06) * (u / 0.06)) + 1;
        const double cosine = std::cos(tilt) * std::cos(theta) + std::sin(tilt) * std::sin(theta) * std::cos(phi);
        t.push_back(float(d * u * std::sin(theta) * std::max(cosine, 0.0)));
      }
  return t;
}

// The table's nodes at the coarse nodes, bilinearly: what resampling by point samples gives.
std::vector<float> point_samples(const std::vector<float>& t, std::size_t w, std::size_t h, std::size_t nw,
                                 std::size_t nh) {
  std::vector<float> out;
  for (std::size_t s = 0; s < t.size() / (w * h); ++s)
    for (std::size_t j = 0; j < nh; ++j)
      for (std::size_t i = 0; i < nw; ++i) {
        const double x = double(i) / double(nw - 1) * double(w - 1), y = double(j) / double(nh - 1) * double(h - 1);
        const std::size_t ix = std::min(std::size_t(x), w - 2), iy = std::min(std::size_t(y), h - 2);
        const double fx = x - double(ix), fy = y - double(iy);
        const float* p = t.data() + s * w * h + iy * w + ix;
        out.push_back(float((1 - fy) * ((1 - fx) * p[0] + fx * p[1]) + fy * ((1 - fx) * p[w] + fx * p[w + 1])));
      }
  return out;
}

// Per slice, the integral of the bilinear interpolant over [0, 1]^2 (the trapezoid rule is exact for it).
std::vector<double> integrals(const std::vector<float>& t, std::size_t w, std::size_t h) {
  std::vector<double> out;
  for (std::size_t s = 0; s < t.size() / (w * h); ++s) {
    double sum = 0;
    for (std::size_t j = 0; j < h; ++j)
      for (std::size_t i = 0; i < w; ++i)
        sum += (i == 0 || i + 1 == w ? 0.5 : 1.0) * (j == 0 || j + 1 == h ? 0.5 : 1.0) * t[s * w * h + j * w + i];
    out.push_back(sum / double((w - 1) * (h - 1)));
  }
  return out;
}

// Over a lattice of the sample square and both slices, how far b's inverse warp puts each point that a's warp sends
// to a direction (where b would look up a file's stored values that a tabulated there): the mean distance, and the
// largest in y alone (the marginal over rows).
std::pair<double, double> warp_distance(const Warp2D& a, const Warp2D& b) {
  double sum = 0, most_y = 0;
  int n = 0;
  for (const double slice : {0.0, 1.0})
    for (int j = 0; j < 61; ++j)
      for (int i = 0; i < 61; ++i) {
        const double x = (i + 0.5) / 61, y = (j + 0.5) / 61, p[] = {slice};
        const WarpPoint m = a.sample(x, y, p), back = b.invert(m.x, m.y, p);
        sum += std::hypot(back.x - x, back.y - y);
        most_y = std::max(most_y, std::abs(back.y - y));
        ++n;
      }
  return {sum / n, most_y};
}

TEST(ResampleDensity, KeepsTheWarpOfASharpPeakWherePointSamplesLoseIt) {
  const std::vector<float> fine = glossy_density(128, 128);
  const std::vector<float> coarse = resample_density(fine, 128, 128, 32, 32);
  ASSERT_EQ(coarse.size(), 2u * 32 * 32);
  EXPECT_TRUE(std::all_of(coarse.begin(), coarse.end(), [](float v) { return v >= 0; }));
  const std::vector<double> before = integrals(fine, 128, 128), after = integrals(coarse, 32, 32);
  for (std::size_t s = 0; s < 2; ++s) EXPECT_NEAR(after[s], before[s], 1e-5 * before[s]);
  const std::vector<std::vector<float>> slices{{0.0f, 1.0f}};
  const Warp2D original(fine, 128, 128, slices, true), resampled(coarse, 32, 32, slices, true),
      pointwise(point_samples(fine, 128, 128, 32, 32), 32, 32, slices, true);
  const auto [mean, most_y] = warp_distance(original, resampled);
  const auto [point_mean, point_most_y] = warp_distance(original, pointwise);
  std::printf("sample points off the 128^2 table's: resampled mean %.5f, in y at most %.5f; point samples %.5f, %.5f\n",
              mean, most_y, point_mean, point_most_y);
  EXPECT_LT(mean, 0.6 * point_mean);
  EXPECT_LT(most_y, 0.1 * point_most_y);
  EXPECT_LT(mean, 0.02 / 31);  // a fiftieth of a 32^2 sample grid's spacing
}

TEST(ResampleDensity, ASideThatKeepsItsSizeKeepsItsNodes) {
  const std::vector<float> fine = glossy_density(64, 16);
  const std::vector<float> same = resample_density(fine, 64, 16, 64, 16);
  EXPECT_TRUE(same.size() == fine.size() && std::memcmp(same.data(), fine.data(), fine.size() * sizeof(float)) == 0);
  // Only the columns resampled: every row keeps its integral (its share of the marginal).
  const std::vector<float> narrow = resample_density(fine, 64, 16, 24, 16);
  for (std::size_t r = 0; r < 2 * 16; ++r) {
    double a = 0, b = 0;
    for (std::size_t i = 0; i + 1 < 64; ++i) a += 0.5 * (fine[r * 64 + i] + fine[r * 64 + i + 1]) / 63;
    for (std::size_t i = 0; i + 1 < 24; ++i) b += 0.5 * (narrow[r * 24 + i] + narrow[r * 24 + i + 1]) / 23;
    EXPECT_NEAR(b, a, 1e-5 * a + 1e-9);
  }
}

TEST(ResampleDensity, RefusesTablesBelowTwoNodesAndSizesThatDisagree) {
  const std::vector<float> t(2 * 3 * 4, 1.0f);
  EXPECT_THROW(resample_density(t, 3, 4, 1, 4), UsageError);
  EXPECT_THROW(resample_density(t, 1, 4, 2, 2), UsageError);
  EXPECT_THROW(resample_density(t, 5, 4, 2, 2), UsageError);
}

}  // namespace
}  // namespace specula::codec
