// The samples a holdout keeps (acquire/scan_holdout.h): read through KeptSamples they are the source's kept rows in
// order, angles, values and variances alike, in reads of any size; a sparse selection reads only the source's blocks
// that hold a kept sample, never more than a block at once.
#include "specula/acquire/scan_holdout.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "specula/core/error.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kN = 10000, kBands = 3, kBlock = 100;

// Samples numbered by their row, in blocks of kBlock, counting every row it reads.
class Counting final : public brdf::SampleSource {
 public:
  std::size_t size() const override { return kN; }
  std::size_t bands() const override { return kBands; }
  std::size_t block_rows() const override { return kBlock; }
  bool has_variance() const override { return true; }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override {
    note(first, count);
    for (std::size_t i = 0; i < count * 4; ++i) out[i] = double(first * 4 + i);
  }
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override {
    note(first, count);
    for (std::size_t i = 0; i < count * kBands; ++i) out[i] = float(first * kBands + i);
  }
  void read_variance(std::size_t first, std::size_t count, std::span<float> out) const override {
    note(first, count);
    for (std::size_t i = 0; i < count * kBands; ++i) out[i] = -float(first * kBands + i);
  }
  mutable std::size_t rows_read = 0, largest_read = 0;

 private:
  void note(std::size_t first, std::size_t count) const {
    ASSERT_LE(first + count, kN);
    rows_read += count;
    largest_read = std::max(largest_read, count);
  }
};

TEST(KeptSamples, AreTheKeptRowsInOrderReadBlockByBlock) {
  // Kept: the lone rows 500, 1500, ..., 9500 and the dense run 4000..4499 less every third row; the rest held.
  std::vector<std::uint8_t> held(kN, 1);
  std::vector<std::size_t> kept;
  for (std::size_t s = 0; s < kN; ++s)
    if (s % 1000 == 500 || (s >= 4000 && s < 4500 && s % 3 != 0)) {
      held[s] = 0;
      kept.push_back(s);
    }
  const Counting src;
  const KeptSamples k(src, held);
  ASSERT_EQ(k.size(), kept.size());
  EXPECT_EQ(k.bands(), kBands);
  EXPECT_TRUE(k.has_variance());
  for (const std::size_t step : {std::size_t(1), std::size_t(7), std::size_t(64), kept.size()}) {
    src.rows_read = src.largest_read = 0;
    for (std::size_t first = 0; first < kept.size(); first += step) {
      const std::size_t count = std::min(step, kept.size() - first);
      std::vector<double> angles(count * 4);
      std::vector<float> values(count * kBands), variance(count * kBands);
      k.read_angles(first, count, angles);
      k.read_values(first, count, values);
      k.read_variance(first, count, variance);
      for (std::size_t i = 0; i < count; ++i) {
        const std::size_t s = kept[first + i];
        for (std::size_t j = 0; j < 4; ++j) ASSERT_EQ(angles[i * 4 + j], double(s * 4 + j)) << "row " << s;
        for (std::size_t j = 0; j < kBands; ++j) {
          ASSERT_EQ(values[i * kBands + j], float(s * kBands + j)) << "row " << s;
          ASSERT_EQ(variance[i * kBands + j], -float(s * kBands + j)) << "row " << s;
        }
      }
    }
    EXPECT_LE(src.largest_read, kBlock) << "reads of " << step;
    // Read whole (three kinds), the selection costs at most the 10 lone rows and the run's 500 rows from its first kept
    // row to its last: by blocks, no read spans the rows between two lone rows.
    if (step == kept.size()) {
      EXPECT_LE(src.rows_read, 3 * (10 + 500)) << "reads of " << step;
      EXPECT_GE(src.rows_read, 3 * kept.size()) << "reads of " << step;
    }
  }
  std::vector<float> two(2 * kBands);
  EXPECT_THROW(k.read_values(kept.size() - 1, 2, two), UsageError);
}

}  // namespace
}  // namespace specula::acquire
