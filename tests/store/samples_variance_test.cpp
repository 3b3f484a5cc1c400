// Samples with a per-value noise variance (samples_version 2): the variance round-trips beside the values, its
// misuse is refused, and a store of samples written before variances existed (tests/store/data/samples-v1, made by
// the previous specula) still reads, without one.
#include <gtest/gtest.h>

#include <filesystem>

#include "specula/core/error.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

TEST(SamplesVariance, RoundTripsBesideTheValuesAndMisuseIsRefused) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.create_samples("noisy", WavelengthGrid({500, 600}), "1/sr", {}, true);
    w.create_samples("plain", WavelengthGrid({500, 600}), "1/sr", {});
    const std::vector<double> a{0.1, 0.2, 0.3, 0.4, 1, 2, 3, 0.5};
    const std::vector<float> v{10, 11, 20, 21}, var{0.5, 0.25, 2, 4};
    w.append_samples("noisy", a, v, var);
    w.append_samples("noisy", std::vector<double>{0.2, 0.2, 0.2, 0.2}, std::vector<float>{5, 6},
                     std::vector<float>{1, 0});
    EXPECT_THROW(w.append_samples("noisy", a, v), UsageError);  // a variance per value is required
    EXPECT_THROW(w.append_samples("plain", a, v, var), UsageError);
    EXPECT_THROW(w.append_samples("noisy", a, v, std::vector<float>{0.5, -1, 2, 4}), InputError);
    w.append_samples("plain", a, v);
    w.commit();
  }
  const Store s = Store::open(path);
  const SamplesInfo noisy = s.samples_info("noisy"), plain = s.samples_info("plain");
  EXPECT_TRUE(noisy.variance);
  EXPECT_FALSE(plain.variance);
  ASSERT_EQ(noisy.size, 3u);
  std::vector<float> values(6), var(6);
  s.read_samples("noisy", 0, 3, {}, values, var);
  EXPECT_EQ(values, (std::vector<float>{10, 11, 20, 21, 5, 6}));
  EXPECT_EQ(var, (std::vector<float>{0.5, 0.25, 2, 4, 1, 0}));
  std::vector<float> one(2);
  s.read_samples("noisy", 1, 1, {}, {}, one);
  EXPECT_EQ(one, (std::vector<float>{2, 4}));
  EXPECT_THROW(s.read_samples("plain", 0, 1, {}, {}, one), UsageError);
}

TEST(SamplesVariance, SamplesWrittenBeforeVariancesExistedStillRead) {
  test::ScratchDir dir;
  std::filesystem::copy(SPECULA_SOURCE_DIR "/tests/store/data/samples-v1", dir.path(),
                        std::filesystem::copy_options::recursive);
  const Store s = Store::open(dir / "old-samples.h5");
  const SamplesInfo info = s.samples_info("old");
  EXPECT_FALSE(info.variance);
  ASSERT_EQ(info.size, 20u);
  ASSERT_EQ(info.bands, 3u);
  std::vector<double> angles(4);
  std::vector<float> values(3);
  s.read_samples("old", 0, 1, angles, values);
  // As h5py reads the file.
  EXPECT_EQ(values, (std::vector<float>{0.021427804604172707f, 0.177338644862175f, 0.01697596348822117f}));
  EXPECT_EQ(angles[1], 1.326626206387806);
}
