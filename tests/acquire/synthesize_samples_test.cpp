// synthesize_samples: the batches it hands over against the pieces it is made of, and even thinning to a count.
#include <gtest/gtest.h>

#include "specula/acquire/synth_samples.h"
#include "specula/core/brdf_materials.h"

using namespace specula;

TEST(SynthesizeSamples, RandomConfigurationsOneBlock) {
  const WavelengthGrid g = WavelengthGrid::range(450, 650, 50);
  const auto model = brdf::make_material("gold", g);
  std::vector<double> got_a;
  std::vector<float> got_v;
  std::size_t batches = 0;
  const acquire::SynthesisCount n = acquire::synthesize_samples(
      *model, {.geometry = acquire::SampleSynthesis::Geometry::random, .count = 1000, .noise = 0.05, .seed = 9},
      [&](std::span<const double> a, std::span<const float> v) {
        got_a.assign(a.begin(), a.end());
        got_v.assign(v.begin(), v.end());
        ++batches;
      });
  EXPECT_EQ(n.samples, 1000u);
  EXPECT_EQ(batches, 1u);
  std::vector<double> a;
  acquire::random_configurations(1000, 9, 0, a);
  std::vector<float> v(1000 * g.size());
  acquire::evaluate_noisy(*model, a, v, 0.05, 9, 0);
  EXPECT_EQ(got_a, a);
  EXPECT_EQ(got_v, v);
}

TEST(SynthesizeSamples, ScanThinnedToACount) {
  const WavelengthGrid g = WavelengthGrid::range(500, 600, 50);
  const auto model = brdf::make_material("green-matte", g);
  acquire::SampleSynthesis s;
  s.rig.sphere_px = 40;
  s.rig.lights = 12;
  std::size_t all = 0, batches = 0;
  const acquire::SynthesisCount full =
      acquire::synthesize_samples(*model, s, [&](std::span<const double> a, std::span<const float> v) {
        EXPECT_EQ(v.size(), a.size() / 4 * g.size());
        all += a.size() / 4;
        ++batches;
      });
  EXPECT_EQ(batches, 12u);
  EXPECT_EQ(full.samples, all);
  EXPECT_EQ(full.pixels, acquire::scan_pixels(s.rig).size());
  ASSERT_GT(all, 200u);
  s.count = 200;
  std::size_t kept = 0;
  const acquire::SynthesisCount thin = acquire::synthesize_samples(
      *model, s, [&](std::span<const double> a, std::span<const float>) { kept += a.size() / 4; });
  EXPECT_EQ(kept, 200u);
  EXPECT_EQ(thin.samples, 200u);
}
