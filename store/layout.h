#pragma once
// The version-2 store on disk (docs/store-format.md): a small root file holding the index and one HDF5 external link
// per object, beside a data directory of immutable object files. This header is the store library's own: the commit
// protocol, the locks that serialise commits and protect readers, and garbage collection.
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace specula::store::layout {

/// The top-level groups that hold objects, one kind each.
inline constexpr std::string_view kKinds[] = {"images", "collections",  "samples", "grids",
                                              "bases",  "coefficients", "acquire", "priors"};
/// True when `kind` is one of kKinds.
bool is_kind(std::string_view kind);

/// One committed object: its data file (relative to the data directory) and what that file held when committed.
struct Entry {
  std::string kind;
  std::string name;
  std::string file;
  std::uint64_t bytes = 0;
  std::uint32_t crc32 = 0;
  long long generation = 0;  ///< the commit that added it
};

/// The committed state a root file describes.
struct Index {
  long long generation = 0;    ///< number of commits so far
  std::string created_utc;     ///< when the store was created
  std::string data_dir;        ///< the data directory's name, beside the root
  std::vector<Entry> entries;  ///< sorted by (kind, name)

  /// The entry of (kind, name), or nullptr.
  const Entry* find(std::string_view kind, std::string_view name) const;
  /// True when some entry's data is `file`.
  bool references(std::string_view file) const;
};

/// A data file that the root stopped referencing at generation `to`; it was referenced from generation `from` on.
struct Garbage {
  std::string file;
  long long from = 0, to = 0;
};

/// "<root>.d": the data directory a new store at `root` gets.
std::filesystem::path default_data_dir(const std::filesystem::path& root);
/// The data directory of a store whose index is `index`.
std::filesystem::path data_dir(const std::filesystem::path& root, const Index& index);

/// Writes a complete version-2 root for `index` at `path` (to be renamed over `root` later) and fsyncs it.
void write_root(const std::filesystem::path& path, const Index& index);

/// CRC-32 (zlib's) and size of a whole file; LibraryError naming the file on an OS failure.
std::uint32_t file_crc32(const std::filesystem::path& path, std::uint64_t& bytes);
/// fsync of a file or directory; LibraryError on failure (directories: best effort).
void sync_path(const std::filesystem::path& path, bool directory = false);
/// Creates `dir` and its parents and fsyncs the parent of each directory created.
void create_directories_synced(const std::filesystem::path& dir);

/// An flock(2) on a lock file, created if absent; released on destruction.
class FileLock {
 public:
  FileLock() = default;
  /// Takes an exclusive lock on `path`, waiting for it unless `wait` is false (then held() tells).
  FileLock(const std::filesystem::path& path, bool wait);
  FileLock(FileLock&& o) noexcept;
  FileLock& operator=(FileLock&& o) noexcept;
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  ~FileLock();
  bool held() const { return fd_ >= 0; }
  /// Unlinks the lock file while still holding it, then releases it.
  void remove();

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

/// A live transaction: a random id and the exclusive lock on <data>/tx/<id>.lock that marks it in flight.
class Transaction {
 public:
  explicit Transaction(const std::filesystem::path& data_dir);
  const std::string& id() const { return id_; }
  /// Removes the lock file; the transaction is over.
  void end() { lock_.remove(); }

 private:
  std::string id_;
  FileLock lock_;
};

/// Data file name for object (kind, name) written by transaction `tx`, relative to the data directory.
std::string object_file(std::string_view kind, std::string_view name, std::string_view tx);

/// What a reader holds while it uses a committed state: a shared byte-range lock (OFD) on byte `generation` of
/// <data>/readers. Garbage collection deletes a file only when no such lock covers a generation that referenced it.
class ReaderLock {
 public:
  ReaderLock() = default;
  /// Locks generation `generation` of the store with data directory `data_dir` (no-op when it has no readers file).
  ReaderLock(const std::filesystem::path& data_dir, long long generation);
  ReaderLock(ReaderLock&& o) noexcept;
  ReaderLock& operator=(ReaderLock&& o) noexcept;
  ReaderLock(const ReaderLock&) = delete;
  ReaderLock& operator=(const ReaderLock&) = delete;
  ~ReaderLock();

 private:
  int fd_ = -1;
};

/// What a collection reclaimed and what it had to leave.
struct Reclaimed {
  std::size_t files = 0;
  std::uint64_t bytes = 0;
  std::size_t in_use = 0;     ///< garbage still visible to a reader
  std::size_t in_flight = 0;  ///< transactions still running
};

/// Under the commit lock of the store at `root`: deletes garbage no reader can see and, when `orphans`, the files of
/// dead transactions (data files, lock files, unrenamed roots); never touches a file `current` references.
Reclaimed collect(const std::filesystem::path& root, const std::filesystem::path& data_dir, const Index& current,
                  bool orphans);
/// Adds `more` to the garbage list of the data directory (write-ahead of a commit that drops those files).
void append_garbage(const std::filesystem::path& data_dir, const std::vector<Garbage>& more);
/// The number of transactions other than `own` whose lock is held.
std::size_t transactions_in_flight(const std::filesystem::path& data_dir, std::string_view own);

/// Checks that the store at `root` owns `data_dir` (recorded in <data>/owner, adopted after a rename of the root);
/// InputError when the directory belongs to another existing root, i.e. `root` is a copy of that root alone.
void claim_data_dir(const std::filesystem::path& root, const std::filesystem::path& data_dir);

/// Test hook: SPECULA_TEST_CRASH_AT=<point> kills the process with SIGKILL at that named point of a commit.
void crash_point(std::string_view point);

}  // namespace specula::store::layout
