// A store's samples read through StoreSamples in blocks against the same samples held in memory.
#include "specula/acquire/store_samples.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <span>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula::acquire {
namespace {

struct Samples {
  std::vector<double> angles;
  std::vector<float> values;
};

// n samples at random directions of the upper hemisphere with `bands` values varying smoothly over them.
Samples smooth_samples(std::size_t n, std::size_t bands) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> theta(0.0, 1.5), phi(0.0, 6.283);
  Samples s;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = theta(rng), pi_ = phi(rng), to = theta(rng), po = phi(rng);
    s.angles.insert(s.angles.end(), {ti, pi_, to, po});
    for (std::size_t q = 0; q < bands; ++q)
      s.values.push_back(float(1 + std::cos(ti + 0.1 * double(q)) * std::cos(to) + 0.1 * std::cos(po - pi_)));
  }
  return s;
}

TEST(StoreSamples, GiveTheSameGridAsMemory) {
  test::ScratchDir dir;
  const Samples s = smooth_samples(50000, 4);
  {
    store::StoreWriter w(dir / "s.h5", {});
    w.create_samples("scan", WavelengthGrid::parse("400:700:100"), "1/sr", {});
    // Appended in uneven batches, as a capture would.
    w.append_samples("scan", std::span(s.angles).subspan(0, 4 * 12345), std::span(s.values).subspan(0, 4 * 12345));
    w.append_samples("scan", std::span(s.angles).subspan(4 * 12345), std::span(s.values).subspan(4 * 12345));
    w.commit();
  }
  const store::Store st = store::Store::open(dir / "s.h5");
  const StoreSamples src(st, "scan");
  EXPECT_EQ(src.size(), 50000u);
  EXPECT_EQ(src.bands(), 4u);
  EXPECT_EQ(src.block_rows() % st.samples_info("scan").chunk_rows, 0u);
  const brdf::ResampleOptions o{.k = 12};
  std::vector<float> a(4 * brdf::kMerlCells), b(4 * brdf::kMerlCells);
  const brdf::GridStats stats = brdf::resample_grid(src, o, a);
  EXPECT_EQ(stats.samples, 50000u);
  brdf::Resampler(s.angles, s.values, 4, o).fill_grid(b);
  EXPECT_TRUE(a == b);
  EXPECT_THROW(StoreSamples(st, "missing"), InputError);
}

}  // namespace
}  // namespace specula::acquire
