#pragma once
// The one parallel loop of specula: indices spread over OpenMP threads, state per thread, interruption checked
// between items, and the first exception rethrown on the calling thread (items not yet started are skipped).
// Header-only: it needs no OpenMP runtime of core, only the including library's -fopenmp (serial without it).
#include <atomic>
#include <concepts>
#include <cstddef>
#include <exception>
#include <mutex>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "specula/core/interrupt.h"

namespace specula {

/// Runs body(i, state) for every i in [0, n) on all OpenMP threads, in chunks of `grain` consecutive indices handed
/// out dynamically, each thread with its own state from make_state(); checks for interruption before each chunk and
/// rethrows the first exception (or Interrupted) here. Results that must not depend on the thread count belong in
/// per-index slots merged in index order by the caller.
template <class MakeState, class Body>
requires std::invocable<MakeState&>
void parallel_for(std::size_t n, MakeState&& make_state, Body&& body, std::size_t grain = 1) {
  if (grain == 0) grain = 1;
  const long long chunks = static_cast<long long>((n + grain - 1) / grain);
  std::exception_ptr error;
  std::mutex error_mutex;
  std::atomic<bool> failed{false};
#pragma omp parallel
  {
    auto state = make_state();
#pragma omp for schedule(dynamic, 1)
    for (long long c = 0; c < chunks; ++c) {
      if (failed.load(std::memory_order_relaxed)) continue;
      try {
        check_interrupt();
        const std::size_t first = std::size_t(c) * grain, last = first + grain < n ? first + grain : n;
        for (std::size_t i = first; i < last; ++i) body(i, state);
      } catch (...) {
        std::lock_guard lock(error_mutex);
        if (!error) error = std::current_exception();
        failed.store(true, std::memory_order_relaxed);
      }
    }
  }
  if (error) std::rethrow_exception(error);
}

/// As above for loops that need no per-thread state: body(i).
template <class Body>
void parallel_for(std::size_t n, Body&& body, std::size_t grain = 1) {
  parallel_for(
      n, [] { return 0; }, [&](std::size_t i, int&) { body(i); }, grain);
}

/// Runs body(first, last) over contiguous, disjoint shares of [0, n) that together cover it, one share per OpenMP
/// thread (at most n), each share wholly on one thread; for work that sweeps shared data once per share and
/// accumulates per index. Interruption and exceptions as parallel_for. Results do not depend on the thread count
/// when body treats every index the same whatever share holds it.
template <class Body>
void parallel_shares(std::size_t n, Body&& body) {
#ifdef _OPENMP
  const std::size_t threads = static_cast<std::size_t>(omp_get_max_threads());
#else
  const std::size_t threads = 1;
#endif
  const std::size_t shares = n < threads ? n : threads;
  parallel_for(shares, [&](std::size_t s) { body(s * n / shares, (s + 1) * n / shares); });
}

}  // namespace specula
