// Each sample's variance from the camera's noise model (acquire/sample_noise.h), checked against the scatter of
// the same samples over repeated simulated captures that differ only in their noise seed: the closed-form
// propagation (merge, flat field, irradiance, recovery) must predict the empirical variance, at low and high signal.
#include "specula/acquire/sample_noise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>

#include "small_rig.h"
#include "specula/acquire/pipeline.h"
#include "specula/acquire/store_samples.h"
#include "specula/core/brdf_resample.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;

TEST(SampleNoise, PredictedVarianceMatchesTheScatterOfRepeatedCaptures) {
  test::ScratchDir dir;
  SimulatorOptions o = test::small_rig(96, 64, 2, 40, {450, 550, 650}, true);
  o.passband = Passband::delta;
  // One calibration for every repeat: only the scene images' noise differs between them.
  simulate_capture(o, dir / "c0");
  const Capture cap0 = read_manifest(dir / "c0");
  const Calibration c = calibrate_capture(cap0, dir / "c0", {});
  constexpr int K = 6;
  {
    store::StoreWriter w(dir / "s.h5", {});
    for (int k = 1; k <= K; ++k) {
      o.seed = unsigned(100 + k);
      const std::string cap = "c" + std::to_string(k);
      simulate_capture(o, dir / cap);
      extract_samples(read_manifest(dir / cap), dir / cap, c, {}, w, "s" + std::to_string(k));
    }
    w.commit();
  }
  const store::Store s = store::Store::open(dir / "s.h5");
  // The same (pixel, light) has the same angles in every repeat: match samples by them.
  using Key = std::array<double, 4>;
  std::map<Key, std::vector<std::pair<std::array<float, 3>, std::array<float, 3>>>> by_key;
  for (int k = 1; k <= K; ++k) {
    const std::string name = "s" + std::to_string(k);
    const store::SamplesInfo info = s.samples_info(name);
    ASSERT_TRUE(info.variance);
    ASSERT_TRUE(StoreSamples(s, name).has_variance());
    std::vector<double> a(4 * info.size);
    std::vector<float> v(3 * info.size), var(3 * info.size);
    s.read_samples(name, 0, info.size, a, v, var);
    for (std::size_t i = 0; i < info.size; ++i)
      by_key[{a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3]}].push_back(
          {{v[3 * i], v[3 * i + 1], v[3 * i + 2]}, {var[3 * i], var[3 * i + 1], var[3 * i + 2]}});
  }
  // Per sample and band: the empirical variance over the repeats against the mean predicted one.
  std::vector<std::pair<double, double>> rel_and_ratio;  // predicted relative variance, empirical / predicted
  for (const auto& [key, reps] : by_key) {
    if (reps.size() != std::size_t(K)) continue;  // rejected in some repeat (saturation, low signal)
    for (std::size_t b = 0; b < 3; ++b) {
      double mean = 0, predicted = 0, scatter = 0;
      for (const auto& r : reps) mean += r.first[b] / double(K), predicted += r.second[b] / double(K);
      for (const auto& r : reps) scatter += (r.first[b] - mean) * (r.first[b] - mean) / double(K - 1);
      ASSERT_GT(predicted, 0);
      rel_and_ratio.emplace_back(predicted / (mean * mean), scatter / predicted);
    }
  }
  ASSERT_GT(rel_and_ratio.size(), 6000u);
  std::ranges::sort(rel_and_ratio);
  // The lower and upper halves by relative noise (bright and dim readings): each ratio's mean is 1 within a few
  // standard errors (a ratio of K - 1 degrees of freedom has variance 2 / (K - 1)).
  const std::size_t half = rel_and_ratio.size() / 2;
  double low = 0, high = 0;
  for (std::size_t i = 0; i < half; ++i) low += rel_and_ratio[i].second / double(half);
  for (std::size_t i = half; i < 2 * half; ++i) high += rel_and_ratio[i].second / double(half);
  EXPECT_NEAR(low, 1.0, 0.06);
  EXPECT_NEAR(high, 1.0, 0.06);
  // The halves differ in noise by more than the tolerance, so a variance of the wrong signal dependence fails.
  EXPECT_GT(rel_and_ratio[3 * half / 2].first / rel_and_ratio[half / 2].first, 3.0);
}
