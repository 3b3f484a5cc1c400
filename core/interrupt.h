#pragma once
// Cooperative interruption: apps/ installs the signal handler, long loops poll.

namespace specula {

/// Installs SIGINT/SIGTERM handlers that request a stop (a second signal removes temporaries and exits 130).
void install_interrupt_handlers();
/// Requests a stop as a signal would (used by tests).
void request_interrupt() noexcept;
/// Clears a pending request.
void clear_interrupt() noexcept;
/// True once a stop was requested.
bool interrupt_requested() noexcept;
/// Throws specula::Interrupted if a stop was requested.
void check_interrupt();

}  // namespace specula
