#include "specula/core/atomic_file.h"

#include <fcntl.h>
#include <linux/fs.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>

#include "specula/core/error.h"

namespace specula {
namespace {

// Registry of live temporaries for the signal handler: fixed slots of plain char arrays.
constexpr std::size_t kSlots = 64;
constexpr std::size_t kPathMax = 4096;
std::array<std::atomic<bool>, kSlots> g_used{};
std::array<std::array<char, kPathMax>, kSlots> g_paths{};
std::atomic<unsigned> g_counter{0};

int register_temp(const std::filesystem::path& p) {
  const std::string s = p.string();
  if (s.size() >= kPathMax) return -1;
  for (std::size_t i = 0; i < kSlots; ++i) {
    bool expected = false;
    if (g_used[i].compare_exchange_strong(expected, true)) {
      std::memcpy(g_paths[i].data(), s.c_str(), s.size() + 1);
      return int(i);
    }
  }
  return -1;
}

void unregister_temp(int slot) {
  if (slot >= 0) g_used[std::size_t(slot)].store(false);
}

std::string os_error(const std::string& what, const std::filesystem::path& p) {
  return p.string() + ": " + what + ": " + std::strerror(errno);
}

// Copies src to dst, sharing extents (reflink) when the filesystem can, else copy_file_range.
void clone_file(const std::filesystem::path& src, const std::filesystem::path& dst) {
  int in = ::open(src.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) throw LibraryError(os_error("cannot open", src));
  struct stat st {};
  if (::fstat(in, &st) != 0) {
    ::close(in);
    throw LibraryError(os_error("cannot stat", src));
  }
  int out = ::open(dst.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, st.st_mode & 0777);
  if (out < 0) {
    ::close(in);
    throw LibraryError(os_error("cannot create", dst));
  }
  bool ok = ::ioctl(out, FICLONE, in) == 0;
  if (!ok) {
    off_t remaining = st.st_size;
    while (remaining > 0) {
      ssize_t n = ::copy_file_range(in, nullptr, out, nullptr, std::size_t(remaining), 0);
      if (n <= 0) break;
      remaining -= n;
    }
    ok = remaining == 0;
  }
  const int saved = errno;
  ::close(in);
  ::close(out);
  if (!ok) {
    errno = saved;
    throw LibraryError(os_error("cannot copy to temporary " + dst.filename().string(), src));
  }
}

}  // namespace

AtomicOutput::AtomicOutput(std::filesystem::path target, bool copy_existing) : target_(std::move(target)) {
  if (target_.filename().empty()) throw UsageError("output path '" + target_.string() + "' names no file");
  const auto dir = target_.parent_path().empty() ? std::filesystem::path(".") : target_.parent_path();
  if (!std::filesystem::is_directory(dir))
    throw InputError(target_.string() + ": directory " + dir.string() + " does not exist");
  temp_ = dir / (target_.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                 std::to_string(g_counter.fetch_add(1)));
  slot_ = register_temp(temp_);
  if (copy_existing && std::filesystem::exists(target_)) {
    try {
      clone_file(target_, temp_);
    } catch (...) {
      std::error_code ec;
      std::filesystem::remove(temp_, ec);
      unregister_temp(slot_);
      throw;
    }
  }
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
  unregister_temp(slot_);
}

void AtomicOutput::commit() {
  if (committed_) throw UsageError("AtomicOutput::commit called twice for " + target_.string());
  int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw LibraryError(os_error("temporary output vanished", temp_));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw LibraryError(os_error("cannot flush", temp_));
  if (::rename(temp_.c_str(), target_.c_str()) != 0) throw LibraryError(os_error("cannot rename over", target_));
  committed_ = true;
  const auto dir = target_.parent_path().empty() ? std::filesystem::path(".") : target_.parent_path();
  int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void remove_pending_temporaries() noexcept {
  for (std::size_t i = 0; i < kSlots; ++i)
    if (g_used[i].load()) ::unlink(g_paths[i].data());
}

}  // namespace specula
