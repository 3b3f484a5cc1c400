// HDR merge in closed form: exact lines give their slope, each kind of pixel gets its status, the order of the
// exposures does not matter, and bad calls throw with the rule; the merged rate's variance against merged simulated
// pixels and closed forms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "specula/acquire/hdr.h"
#include "specula/acquire/simulate.h"
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

// The simulator's sensor (acquire/simulate.cpp's Sensor), written out here: bias + rate t + Gaussian noise of
// variance read^2 + rate t / gain, rounded and clipped to 12 bits.
std::vector<std::vector<std::uint16_t>> simulated_exposures(double rate, const std::vector<double>& times,
                                                            std::size_t pixels, const SensorNoise& n) {
  std::mt19937_64 rng(11);
  std::vector<std::vector<std::uint16_t>> images(times.size(), std::vector<std::uint16_t>(pixels));
  for (std::size_t e = 0; e < times.size(); ++e)
    for (auto& v : images[e]) {
      const double mean = n.dark_dn + rate * times[e];
      const double sigma = std::sqrt(rate * times[e] / n.electrons_per_dn + n.read_noise_dn * n.read_noise_dn);
      v = std::uint16_t(std::clamp(std::lround(mean + std::normal_distribution<double>(0, sigma)(rng)), 0L, 4095L));
    }
  return images;
}

TEST(HdrNoise, TheRatesVarianceMatchesMergedSimulatedPixels) {
  const SensorNoise n;
  // Three values in range (LS slope), two, one, none below the range (the longest), none above it (the shortest).
  const std::vector<std::pair<double, std::vector<double>>> cases = {
      {300, {0.1, 0.3, 1, 3, 10}}, {100, {1, 10, 30}}, {100, {3, 100}}, {3, {20, 60}}, {1e5, {0.05, 0.1}}};
  for (const auto& [rate, times] : cases) {
    const auto images = simulated_exposures(rate, times, 40000, n);
    const HdrImage h = merge(images, times);
    double mean = 0, var = 0;
    for (const float r : h.rate) mean += r / double(h.rate.size());
    for (const float r : h.rate) var += (r - mean) * (r - mean) / double(h.rate.size() - 1);
    if (rate > 1e4) {
      // Saturated: merge gives no rate; the variance is that of the shortest exposure's value over its time.
      EXPECT_EQ(h.status[0], HdrStatus::saturated);
      EXPECT_DOUBLE_EQ(hdr_rate_variance(rate, times, 12, n),
                       (n.read_noise_dn * n.read_noise_dn + rate * 0.05 / n.electrons_per_dn + 1.0 / 12) / 0.0025);
      continue;
    }
    EXPECT_NEAR(hdr_rate_variance(rate, times, 12, n) / var, 1.0, 0.04) << rate << " DN/s";
  }
}

TEST(HdrNoise, ClosedFormsOfADimReadingAtTheCapAndOfExposuresInARatio) {
  const SensorNoise n;
  // 3 DN/s at the 60 s cap: 188 DN, below the range; its value over 60 s.
  EXPECT_DOUBLE_EQ(hdr_rate_variance(3, std::vector<double>{20, 60}, 12, n), (2.25 + 3 * 60 / 4.0 + 1.0 / 12) / 3600);
  // Shot noise alone: one exposure 4 times longer gives a variance 4 times smaller (to the rounding's 1/12).
  const SensorNoise shot{.read_noise_dn = 0};
  const double v1 = hdr_rate_variance(800, std::vector<double>{1}, 12, shot),
               v4 = hdr_rate_variance(800, std::vector<double>{4}, 12, shot);
  EXPECT_DOUBLE_EQ(v1, 800 / 4.0 + 1.0 / 12);
  EXPECT_NEAR(v1 / v4, 4, 2e-3);
  // The defaults are the simulator's sensor.
  const SimulatorOptions sim;
  EXPECT_EQ(n.read_noise_dn, sim.read_noise_dn);
  EXPECT_EQ(n.electrons_per_dn, sim.electrons_per_dn);
  EXPECT_EQ(n.dark_dn, sim.dark_dn);
  EXPECT_THROW(hdr_rate_variance(-1, std::vector<double>{1}, 12, n), UsageError);
  EXPECT_THROW(hdr_rate_variance(1, std::vector<double>{}, 12, n), UsageError);
  EXPECT_THROW(hdr_rate_variance(1, std::vector<double>{1}, 12, {.electrons_per_dn = 0}), UsageError);
}
