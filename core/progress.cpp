#include "specula/core/progress.h"

#include <unistd.h>
#include <cstdio>

namespace specula {
namespace {
std::atomic<bool> g_quiet{false};
std::atomic<bool> g_drawing{false};  // one bar on the terminal at a time
}  // namespace

void set_progress_quiet(bool quiet) noexcept { g_quiet = quiet; }
bool progress_enabled() noexcept { return !g_quiet && ::isatty(STDERR_FILENO) == 1; }

Progress::Progress(std::string label, std::uint64_t total)
    : label_(std::move(label)),
      total_(total),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_),
      enabled_(false) {
  bool idle = false;
  enabled_ = progress_enabled() && g_drawing.compare_exchange_strong(idle, true);
}

Progress::~Progress() {
  if (enabled_) {
    std::lock_guard lock(mutex_);
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
    g_drawing = false;
  }
}

void Progress::advance(std::uint64_t n) {
  done_.fetch_add(n, std::memory_order_relaxed);
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  draw(false);
}

void Progress::draw(bool) {
  const std::uint64_t done = std::min(done_.load(), total_);
  const double frac = total_ ? double(done) / double(total_) : 1.0;
  const int width = 30;
  const int fill = int(frac * width);
  char bar[width + 1];
  for (int i = 0; i < width; ++i) bar[i] = i < fill ? '#' : '.';
  bar[width] = 0;
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double eta = frac > 0 ? secs * (1 - frac) / frac : 0;
  std::fprintf(stderr, "\r\033[K%s [%s] %5.1f%%  %.0fs left", label_.c_str(), bar, 100 * frac, eta);
  std::fflush(stderr);
}

}  // namespace specula
