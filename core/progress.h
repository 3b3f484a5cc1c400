#pragma once
// Progress reporting: a bar on a terminal, silent when stderr is not a TTY or when quiet.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace specula {

/// Global switch set by --quiet.
void set_progress_quiet(bool quiet) noexcept;
/// True when progress bars will be drawn (stderr is a terminal and not quiet).
bool progress_enabled() noexcept;

/// A progress bar over `total` units of work; advance() is thread-safe; the bar is erased on destruction. A bar made
/// while another is shown stays silent, so work inside a larger task (a file of an import) draws no second bar.
class Progress {
 public:
  Progress(std::string label, std::uint64_t total);
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  ~Progress();
  /// Adds n finished units and redraws at most ten times a second.
  void advance(std::uint64_t n = 1);

 private:
  void draw(bool final);
  std::string label_;
  std::uint64_t total_;
  std::atomic<std::uint64_t> done_{0};
  std::chrono::steady_clock::time_point start_, last_draw_;
  std::mutex mutex_;
  bool enabled_;
};

}  // namespace specula
