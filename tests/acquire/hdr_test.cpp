// HDR merge in closed form: exact lines give their slope, each kind of pixel gets its status, the order of the
// exposures does not matter, and bad calls throw with the rule.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "specula/acquire/hdr.h"
#include "specula/core/error.h"

using namespace specula;
using namespace specula::acquire;

namespace {

HdrImage merge(const std::vector<std::vector<std::uint16_t>>& images, const std::vector<double>& times,
               const HdrOptions& o = {}) {
  std::vector<std::span<const std::uint16_t>> views(images.begin(), images.end());
  return merge_exposures(views, times, 12, o);
}

TEST(Hdr, ExactLinesGiveTheirSlopeWhateverTheBias) {
  // value = bias + rate t, all inside [241, 3854] of 4095.
  const std::vector<double> times = {0.5, 1, 2, 3};
  const std::vector<double> rates = {400, 1000, 1200};
  const std::vector<double> bias = {8, 100, 0};
  std::vector<std::vector<std::uint16_t>> images(times.size(), std::vector<std::uint16_t>(rates.size()));
  for (std::size_t e = 0; e < times.size(); ++e)
    for (std::size_t p = 0; p < rates.size(); ++p) images[e][p] = std::uint16_t(bias[p] + rates[p] * times[e]);
  // Pixel 2 at 3 s is 3600: in range; pixel 1 at 3 s is 3100.
  const HdrImage h = merge(images, times);
  for (std::size_t p = 0; p < rates.size(); ++p) {
    EXPECT_EQ(h.status[p], HdrStatus::ok) << p;
    EXPECT_NEAR(h.rate[p], rates[p], 1e-3) << p;
    EXPECT_NEAR(h.pearson[p], 1.0, 1e-9) << p;
  }
  EXPECT_EQ(h.used[0], 3);  // 400 * 0.5 + 8 = 208 is below the range
  EXPECT_EQ(h.used[1], 4);
}

TEST(Hdr, EachPixelGetsItsStatus) {
  const std::vector<double> times = {1, 2, 4, 8};
  // 0: saturated everywhere; 1: below the range everywhere; 2: one value in range; 3: in range but not a line;
  // 4: saturated at long exposures only (the short ones still give the slope).
  const std::vector<std::vector<std::uint16_t>> images = {
      {4095, 10, 20, 500, 1000}, {4095, 20, 40, 3000, 2000}, {4095, 40, 300, 600, 4000}, {4095, 80, 4095, 3500, 4095}};
  const HdrImage h = merge(images, times);
  EXPECT_EQ(h.status[0], HdrStatus::saturated);
  EXPECT_EQ(h.status[1], HdrStatus::low_signal);
  EXPECT_FLOAT_EQ(h.rate[1], 80.0f / 8);
  EXPECT_EQ(h.status[2], HdrStatus::single);
  EXPECT_FLOAT_EQ(h.rate[2], 300.0f / 4);
  EXPECT_EQ(h.status[3], HdrStatus::nonlinear);
  EXPECT_LT(h.pearson[3], 0.99);
  EXPECT_EQ(h.status[4], HdrStatus::ok);
  EXPECT_NEAR(h.rate[4], 1000, 1e-3);
  EXPECT_EQ(h.used[4], 2);
}

TEST(Hdr, OrderOfExposuresDoesNotMatter) {
  const std::vector<double> times = {1, 2, 4, 8}, shuffled = {4, 1, 8, 2};
  std::vector<std::vector<std::uint16_t>> a(4, std::vector<std::uint16_t>(50)), b(4, std::vector<std::uint16_t>(50));
  for (std::size_t p = 0; p < 50; ++p)
    for (std::size_t e = 0; e < 4; ++e) {
      const auto v = [&](double t) {
        return std::uint16_t(
            std::min(4095.0, 5 + (30.0 + 40.0 * double(p)) * t + double((p * 7 + std::size_t(t)) % 5)));
      };
      a[e][p] = v(times[e]);
      b[e][p] = v(shuffled[e]);
    }
  const HdrImage x = merge(a, times), y = merge(b, shuffled);
  for (std::size_t p = 0; p < 50; ++p) {
    EXPECT_EQ(x.status[p], y.status[p]) << p;
    EXPECT_NEAR(x.rate[p], y.rate[p], 1e-3 * std::abs(x.rate[p])) << p;
  }
}

TEST(Hdr, BadCallsThrowWithTheRule) {
  const std::vector<std::vector<std::uint16_t>> two = {{1, 2}, {3, 4}};
  EXPECT_THROW(merge(two, {1}), UsageError);
  EXPECT_THROW(merge(two, {1, 0}), UsageError);
  EXPECT_THROW(merge({{1, 2}, {3}}, {1, 2}), UsageError);
  EXPECT_THROW(merge(two, {1, 2}, {.low = 0.5, .high = 0.4}), UsageError);
  std::vector<std::span<const std::uint16_t>> views(two.begin(), two.end());
  const std::vector<double> t = {1, 2};
  EXPECT_THROW(merge_exposures(views, t, 20), UsageError);
}

}  // namespace
