#include "specula/core/buffer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

namespace specula {
namespace {

std::uintptr_t address(const void* p) { return reinterpret_cast<std::uintptr_t>(p); }

TEST(Buffer, LargeBlocksStartOnA2MBBoundaryAndSmallOnesAreOrdinary) {
  constexpr std::size_t kTwoMB = std::size_t(1) << 21;
  Buffer<float> large;
  large.resize(detail::kLargeBlock / sizeof(float) + 1);
  EXPECT_EQ(address(large.data()) % kTwoMB, 0u);
  Buffer<std::int32_t> codes;
  codes.resize(3 * kTwoMB / sizeof(std::int32_t));  // 6 MB: rounded up to whole 2 MB pages inside
  EXPECT_EQ(address(codes.data()) % kTwoMB, 0u);
  Buffer<double> small(1000, 2.5);
  EXPECT_EQ(small.size(), 1000u);
  EXPECT_EQ(small[999], 2.5);
}

// A vector that grows from a small block to a large one and back (shrink_to_fit) keeps its values: each block is
// freed by the path that allocated it.
TEST(Buffer, GrowingAcrossTheLargeThresholdKeepsTheValues) {
  Buffer<std::uint32_t> v;
  const std::size_t n = 3 * detail::kLargeBlock / sizeof(std::uint32_t);
  for (std::uint32_t i = 0; i < n; ++i) v.push_back(i * 2654435761u);
  for (std::uint32_t i = 0; i < n; i += 4099) ASSERT_EQ(v[i], i * 2654435761u) << i;
  v.resize(100);
  v.shrink_to_fit();
  for (std::uint32_t i = 0; i < 100; ++i) ASSERT_EQ(v[i], i * 2654435761u) << i;
  Buffer<std::uint32_t> copy = v, moved = std::move(copy);
  EXPECT_EQ(moved, v);
}

TEST(Buffer, AssignAndValueResizeWriteEveryElement) {
  Buffer<float> v;
  v.assign(detail::kLargeBlock / sizeof(float) * 2, -1.0f);
  EXPECT_EQ(std::count(v.begin(), v.end(), -1.0f), std::ptrdiff_t(v.size()));
  v.resize(v.size() + 10, 7.0f);
  EXPECT_EQ(std::count(v.end() - 10, v.end(), 7.0f), 10);
}

}  // namespace
}  // namespace specula
