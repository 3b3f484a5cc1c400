// parallel_for: every index once, per-thread state, the first exception rethrown and later items skipped,
// interruption, and results in per-index slots independent of the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"

using namespace specula;

TEST(Parallel, EveryIndexOnceWithStatePerThreadAtAnyGrain) {
  for (const std::size_t grain : {1u, 7u, 1000u}) {
    std::vector<int> hits(5003, 0);
    std::atomic<int> states{0};
    parallel_for(
        hits.size(),
        [&] {
          ++states;
          return std::vector<int>(3);
        },
        [&](std::size_t i, std::vector<int>& scratch) {
          scratch[0] = int(i);
          hits[i] += 1 + scratch[0] - int(i);
        },
        grain);
    EXPECT_EQ(std::count(hits.begin(), hits.end(), 1), 5003) << grain;
    EXPECT_LE(states.load(), omp_get_max_threads());
  }
}

TEST(Parallel, FirstExceptionIsRethrownAndLaterItemsAreSkipped) {
  std::atomic<std::size_t> ran{0};
  try {
    parallel_for(100000, [&](std::size_t i) {
      ++ran;
      if (i == 10) throw InputError("item 10 is bad");
    });
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "item 10 is bad");
  }
  EXPECT_LT(ran.load(), 100000u) << "items after the failure kept running";
}

TEST(Parallel, InterruptionStopsTheLoop) {
  request_interrupt();
  std::atomic<std::size_t> ran{0};
  EXPECT_THROW(parallel_for(1000, [&](std::size_t) { ++ran; }), Interrupted);
  clear_interrupt();
  EXPECT_EQ(ran.load(), 0u);
}

TEST(Parallel, SlotsMergedInOrderDoNotDependOnTheThreadCount) {
  auto sum_with = [](int threads) {
    omp_set_num_threads(threads);
    std::vector<double> part(997);
    parallel_for(part.size(), [&](std::size_t i) { part[i] = 1.0 / double(i + 1); });
    return std::accumulate(part.begin(), part.end(), 0.0);
  };
  const double one = sum_with(1), two = sum_with(2);
  omp_set_num_threads(omp_get_num_procs());
  EXPECT_EQ(one, two);
}

// parallel_shares as render_spheres uses it: each index accumulates a sequence of chunks within its share. A serial
// loop in the same order is the reference; every index must lie in exactly one share.
TEST(Parallel, SharesCoverEveryIndexOnceAndPerIndexSumsDoNotDependOnTheThreadCount) {
  constexpr std::size_t chunks = 50;
  auto value = [](std::size_t i, std::size_t c) { return 1.0 / double(1 + i * 7 + c * 3); };
  for (const std::size_t n : {0u, 1u, 37u}) {
    std::vector<double> reference(n, 0.0);
    for (std::size_t c = 0; c < chunks; ++c)
      for (std::size_t i = 0; i < n; ++i) reference[i] += value(i, c);
    auto with = [&](int threads) {
      omp_set_num_threads(threads);
      std::vector<double> acc(n, 0.0);
      std::vector<int> owner(n, 0);
      std::atomic<int> calls{0};
      parallel_shares(n, [&](std::size_t first, std::size_t last) {
        ++calls;
        for (std::size_t c = 0; c < chunks; ++c)
          for (std::size_t i = first; i < last; ++i) acc[i] += value(i, c);
        for (std::size_t i = first; i < last; ++i) ++owner[i];
      });
      EXPECT_EQ(calls.load(), int(std::min<std::size_t>(n, std::size_t(threads)))) << n;
      EXPECT_EQ(std::size_t(std::count(owner.begin(), owner.end(), 1)), n);
      return acc;
    };
    const std::vector<double> one = with(1), two = with(2);
    omp_set_num_threads(omp_get_num_procs());
    EXPECT_EQ(one, two) << n;
    EXPECT_EQ(one, reference) << n;
  }
}
