#pragma once
// Outputs appear only when complete: write to a temporary sibling, then rename over the target.
#include <filesystem>

namespace specula {

/// A temporary sibling of `target` that becomes `target` only on commit(); removed otherwise.
class AtomicOutput {
 public:
  /// Reserves "<target>.tmp-<pid>-<n>" in the target's directory; copy_existing starts it as a copy of target.
  explicit AtomicOutput(std::filesystem::path target, bool copy_existing = false);
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  ~AtomicOutput();

  /// Where to write now.
  const std::filesystem::path& temp_path() const { return temp_; }
  const std::filesystem::path& target() const { return target_; }
  /// fsyncs the temporary file and renames it over the target; throws LibraryError on OS failure.
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temp_;
  bool committed_ = false;
  int slot_ = -1;
};

/// Removes every temporary registered by live AtomicOutput objects (for signal handlers; async-signal-safe).
void remove_pending_temporaries() noexcept;

}  // namespace specula
