#include "specula/core/interrupt.h"

#include <unistd.h>
#include <atomic>
#include <csignal>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

namespace specula {
namespace {

std::atomic<int> g_requests{0};

extern "C" void on_signal(int) {
  if (g_requests.fetch_add(1) >= 1) {
    remove_pending_temporaries();
    ::_exit(130);
  }
}

}  // namespace

void install_interrupt_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

void request_interrupt() noexcept { g_requests.store(1); }
void clear_interrupt() noexcept { g_requests.store(0); }
bool interrupt_requested() noexcept { return g_requests.load(std::memory_order_relaxed) > 0; }

void check_interrupt() {
  if (interrupt_requested()) throw Interrupted();
}

}  // namespace specula
