#include "specula/core/buffer.h"

#include <gtest/gtest.h>

#include <sys/resource.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

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

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
long minor_faults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}
#endif

// A large output freed and asked for again, as a caller evaluating in a loop does, gets memory whose pages are
// already there: first touching 24 MB of fresh pages costs thousands of faults (12 on 2 MB pages), and a hole the
// allocator cannot reuse is paid again on every call. Blocks of this size come from glibc's heap when its mmap
// threshold is above them and its trim threshold keeps freed memory (both set here, as a process may set them).
// Under ASan, whose allocator holds freed blocks back, the faults are not counted; the blocks are still checked:
// aligned, written whole, and freed by the pointer malloc gave (ASan reports any other).
TEST(Buffer, ALargeBlockFreedAndAskedForAgainComesBackWithItsPages) {
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
  ASSERT_EQ(mallopt(M_MMAP_THRESHOLD, 32 << 20), 1);
  ASSERT_EQ(mallopt(M_TRIM_THRESHOLD, 1 << 30), 1);
#endif
  const std::size_t n = (std::size_t(24) << 20) / sizeof(float);
  // Something allocated after each block outlives it, so the freed block is a hole of its own size rather than
  // part of the heap's free end.
  std::vector<std::unique_ptr<char[]>> objects;
  const auto touch = [n, &objects] {
    Buffer<float> v;
    v.resize(n);
    objects.push_back(std::make_unique_for_overwrite<char[]>(std::size_t(4) << 20));
    EXPECT_EQ(address(v.data()) % (std::size_t(1) << 21), 0u);
    for (std::size_t i = 0; i < n; ++i) v[i] = float(i);
    return v[n / 3] + v[n - 1];
  };
  const float want = float(n / 3) + float(n - 1);
  EXPECT_EQ(touch(), want);
  EXPECT_EQ(touch(), want);
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
  const long before = minor_faults();
#endif
  for (int call = 0; call < 3; ++call) EXPECT_EQ(touch(), want);
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
  const long faults = minor_faults() - before;
  EXPECT_LT(faults, 8) << faults << " faults: each call touched fresh pages";
#endif
}

}  // namespace
}  // namespace specula
