#include "specula/acquire/synth_samples.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// Restores the thread count a test changed.
struct Threads {
  int saved = omp_get_max_threads();
  ~Threads() { omp_set_num_threads(saved); }
};

// Configurations well above the horizon, where every model is positive, spanning several noise pieces.
std::vector<double> configurations(std::size_t n) {
  std::vector<double> a;
  random_configurations(n, 7, 0, a);
  for (std::size_t i = 0; i < n; ++i) {
    a[4 * i] = 0.05 + 0.9 * a[4 * i];
    a[4 * i + 2] = 0.05 + 0.9 * a[4 * i + 2];
  }
  return a;
}

TEST(SynthSamples, WithoutNoiseTheValuesAreThoseOfEvaluateAt) {
  const WavelengthGrid g = WavelengthGrid::parse("420:720:50");
  const auto model = brdf::make_material("study-ward", g);
  const std::size_t n = 3 * kNoisePiece + 17;
  const std::vector<double> a = configurations(n);
  std::vector<float> expected(n * g.size()), got(n * g.size(), -7.0f);
  brdf::evaluate_at(*model, a, expected);
  evaluate_noisy(*model, a, got, 0, 1, 0);
  EXPECT_EQ(got, expected);
}

TEST(SynthSamples, NoiseIsIndependentOfTheThreadCountAndHasTheAskedSpread) {
  Threads restore;
  const WavelengthGrid g = WavelengthGrid::parse("500:600:50");
  const auto model = brdf::make_material("study-ts", g);
  const std::size_t n = 5 * kNoisePiece + 123, b = g.size();
  const std::vector<double> a = configurations(n);
  std::vector<float> clean(n * b), one(n * b), two(n * b), other_batch(n * b);
  brdf::evaluate_at(*model, a, clean);
  const double noise = 0.05;
  omp_set_num_threads(1);
  evaluate_noisy(*model, a, one, noise, 3, 2);
  omp_set_num_threads(2);
  evaluate_noisy(*model, a, two, noise, 3, 2);
  EXPECT_EQ(one, two);
  evaluate_noisy(*model, a, other_batch, noise, 3, 5);
  EXPECT_NE(one, other_batch);  // another batch draws other noise
  // The ratios are 1 + noise N(0, 1): their sample mean and standard deviation within 5 standard errors.
  double sum = 0, sum_sq = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < n * b; ++i) {
    if (!(clean[i] > 0)) continue;
    const double r = double(one[i]) / double(clean[i]);
    sum += r;
    sum_sq += r * r;
    ++count;
  }
  ASSERT_GT(count, n * b / 2);
  const double mean = sum / double(count), sd = std::sqrt(sum_sq / double(count) - mean * mean);
  EXPECT_NEAR(mean, 1, 5 * noise / std::sqrt(double(count)));
  EXPECT_NEAR(sd, noise, 5 * noise / std::sqrt(2.0 * double(count)));
}

TEST(SynthSamples, RejectsNoiseOutsideZeroToOneAndMismatchedSizes) {
  const WavelengthGrid g = WavelengthGrid::parse("500:600:50");
  const auto model = brdf::make_material("study-ts", g);
  std::vector<double> a(8, 0.3);
  std::vector<float> v(2 * g.size());
  EXPECT_THROW(evaluate_noisy(*model, a, v, -0.1, 1, 0), UsageError);
  EXPECT_THROW(evaluate_noisy(*model, a, v, 1.5, 1, 0), UsageError);
  EXPECT_THROW(evaluate_noisy(*model, a, v, std::nan(""), 1, 0), UsageError);
  v.pop_back();
  EXPECT_THROW(evaluate_noisy(*model, a, v, 0, 1, 0), UsageError);
  try {
    evaluate_noisy(*model, a, v, 2, 1, 0);
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("noise"), std::string::npos);
    EXPECT_EQ(std::string(e.what()).find("--"), std::string::npos) << e.what();
  }
}

TEST(SynthSamples, RandomConfigurationsAreUniformOverTheHemisphere) {
  const std::size_t n = 200000;
  std::vector<double> a;
  random_configurations(n, 1, 0, a);
  ASSERT_EQ(a.size(), 4 * n);
  // cos(theta) uniform on [0, 1]: mean 1/2, variance 1/12; phi uniform on [-pi, pi): mean 0, variance pi^2 / 3.
  double c = 0, c2 = 0, p = 0, p2 = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t d : {0, 2}) {
      const double ct = std::cos(a[4 * i + d]), ph = a[4 * i + d + 1];
      ASSERT_GE(ct, 0);
      ASSERT_GE(ph, -pi);
      ASSERT_LT(ph, pi);
      c += ct, c2 += ct * ct, p += ph, p2 += ph * ph;
    }
  const double m = 2.0 * double(n);
  EXPECT_NEAR(c / m, 0.5, 5 * std::sqrt(1.0 / 12 / m));
  EXPECT_NEAR(c2 / m - (c / m) * (c / m), 1.0 / 12, 1e-3);
  EXPECT_NEAR(p / m, 0, 5 * pi / std::sqrt(3 * m));
  EXPECT_NEAR(p2 / m, pi * pi / 3, 0.02);
  std::vector<double> again, other;
  random_configurations(n, 1, 0, again);
  random_configurations(n, 1, 1, other);
  EXPECT_EQ(a, again);
  EXPECT_NE(a, other);
}

TEST(SynthSamples, ThinningKeepsExactlyCountSpreadEvenlyOverTheBatches) {
  const std::size_t total = 1000, count = 137;
  std::size_t seen = 0, kept = 0;
  std::vector<double> firsts;
  for (std::size_t batch : {300u, 1u, 0u, 699u}) {
    std::vector<double> a(4 * batch);
    for (std::size_t i = 0; i < batch; ++i) a[4 * i] = double(seen + i);  // the running index, to see which were kept
    const std::size_t k = thin_evenly(a, seen, count, total);
    ASSERT_EQ(a.size(), 4 * k);
    for (std::size_t i = 0; i < k; ++i) firsts.push_back(a[4 * i]);
    kept += k;
  }
  EXPECT_EQ(seen, total);
  EXPECT_EQ(kept, count);
  // Sample i is kept when floor((i + 1) count / total) steps: the kept indices are ceil(j total / count) - 1.
  for (std::size_t j = 1; j <= count; ++j) EXPECT_EQ(firsts[j - 1], double((j * total + count - 1) / count - 1)) << j;
  std::vector<double> a(8);
  std::size_t s = 0;
  EXPECT_THROW(thin_evenly(a, s, 0, 10), UsageError);
  EXPECT_THROW(thin_evenly(a, s, 10, 10), UsageError);
}

}  // namespace
}  // namespace specula::acquire
