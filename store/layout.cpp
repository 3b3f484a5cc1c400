#include "specula/store/layout.h"

#include <fcntl.h>
#include <libdeflate.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <set>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"
#include "specula/store/h5.h"
#include "specula/version.h"

namespace specula::store::layout {
namespace {

namespace fs = std::filesystem;

std::string os_error(const fs::path& p, const std::string& what) {
  return p.string() + ": " + what + ": " + std::strerror(errno);
}

fs::path garbage_path(const fs::path& data) { return data / "garbage.json"; }
fs::path readers_path(const fs::path& data) { return data / "readers"; }

std::string hex32(std::uint32_t v) {
  char buf[9];
  std::snprintf(buf, sizeof buf, "%08x", v);
  return buf;
}

std::uint32_t parse_hex32(const std::string& s, std::string_view ctx) {
  if (s.size() != 8 || s.find_first_not_of("0123456789abcdef") != std::string::npos)
    throw InputError(std::string(ctx) + ": index has a malformed crc32 '" + s + "'");
  return std::uint32_t(std::stoul(s, nullptr, 16));
}

// The transaction id in a data file name "<...>@<tx>.h5", or "".
std::string tx_of(const std::string& filename) {
  const auto at = filename.rfind('@');
  if (at == std::string::npos || !filename.ends_with(".h5")) return "";
  return filename.substr(at + 1, filename.size() - at - 4);
}

// True when some live process holds the lock of transaction `tx`.
bool tx_alive(const fs::path& data, const std::string& tx) {
  if (tx.empty()) return false;
  const fs::path lock = data / "tx" / (tx + ".lock");
  const int fd = ::open(lock.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool alive = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);
  return alive;
}

std::vector<Garbage> read_garbage(const fs::path& data) {
  std::vector<Garbage> out;
  std::ifstream in(garbage_path(data));
  if (!in) return out;
  nlohmann::json j;
  try {
    in >> j;
    for (const auto& g : j.at("garbage")) out.push_back({g.at("file"), g.at("from"), g.at("to")});
  } catch (const nlohmann::json::exception& e) {
    throw InputError(garbage_path(data).string() + ": malformed garbage list (" + e.what() +
                     "); delete it and run `specula gc` to rebuild it from the files the index does not reference");
  }
  return out;
}

void write_garbage(const fs::path& data, const std::vector<Garbage>& list) {
  nlohmann::json j = {{"garbage", nlohmann::json::array()}};
  for (const auto& g : list) j["garbage"].push_back({{"file", g.file}, {"from", g.from}, {"to", g.to}});
  const fs::path tmp = data / ("garbage.json.tmp-" + std::to_string(::getpid()));
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << j.dump(1) << '\n';
    out.flush();
    if (!out) throw LibraryError(os_error(tmp, "cannot write the garbage list"));
  }
  sync_path(tmp);
  if (::rename(tmp.c_str(), garbage_path(data).c_str()) != 0) throw LibraryError(os_error(tmp, "cannot rename"));
  sync_path(data, true);
}

// True when some reader holds a lock on a generation in [from, to).
bool readers_in(const fs::path& data, long long from, long long to) {
  if (to <= from) return false;
  const int fd = ::open(readers_path(data).c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return false;
  struct flock fl {};
  fl.l_type = F_WRLCK;
  fl.l_whence = SEEK_SET;
  fl.l_start = off_t(from);
  fl.l_len = off_t(to - from);
  const int rc = ::fcntl(fd, F_OFD_GETLK, &fl);
  ::close(fd);
  return rc != 0 || fl.l_type != F_UNLCK;
}

std::uint64_t file_size_or_zero(const fs::path& p) {
  std::error_code ec;
  const auto n = fs::file_size(p, ec);
  return ec ? 0 : n;
}

}  // namespace

bool is_kind(std::string_view kind) {
  return std::find(std::begin(kKinds), std::end(kKinds), kind) != std::end(kKinds);
}

const Entry* Index::find(std::string_view kind, std::string_view name) const {
  for (const auto& e : entries)
    if (e.kind == kind && e.name == name) return &e;
  return nullptr;
}

bool Index::references(std::string_view file) const {
  return std::any_of(entries.begin(), entries.end(), [&](const Entry& e) { return e.file == file; });
}

fs::path default_data_dir(const fs::path& root) { return fs::path(root.string() + ".d"); }

fs::path data_dir(const fs::path& root, const Index& index) {
  if (index.data_dir.empty()) return default_data_dir(root);
  return root.parent_path().empty() ? fs::path(index.data_dir) : root.parent_path() / index.data_dir;
}

Index read_index(hid_t root, std::string_view ctx) {
  Index index;
  index.generation = h5::read_int_attr(root, "generation", ctx);
  index.created_utc = h5::has_attr(root, "created_utc") ? h5::read_string_attr(root, "created_utc", ctx) : "";
  index.data_dir = h5::read_string_attr(root, "data_dir", ctx);
  if (index.data_dir.empty() || index.data_dir.find('/') != std::string::npos || index.data_dir[0] == '.')
    throw InputError(std::string(ctx) + ": attribute data_dir '" + index.data_dir + "' is not a directory name");
  if (!h5::exists(root, "index")) throw InputError(std::string(ctx) + ": dataset '/index' is missing");
  h5::Id ds(h5::check(H5Dopen2(root, "index", H5P_DEFAULT), ctx, "cannot open /index"));
  h5::Id type(h5::check(H5Dget_type(ds), ctx, "H5Dget_type"));
  if (H5Tget_class(type) != H5T_STRING || H5Tis_variable_str(type) <= 0)
    throw InputError(std::string(ctx) + ": /index is not a variable-length string");
  char* raw = nullptr;
  h5::check(H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, &raw), ctx, "cannot read /index");
  const std::string text = raw ? raw : "";
  H5free_memory(raw);
  try {
    const auto j = nlohmann::json::parse(text);
    for (const auto& o : j.at("objects")) {
      Entry e;
      e.kind = o.at("kind");
      e.name = o.at("name");
      e.file = o.at("file");
      e.bytes = o.at("bytes");
      e.crc32 = parse_hex32(o.at("crc32"), ctx);
      e.generation = o.at("generation");
      if (!is_kind(e.kind) || e.name.empty() || e.file.empty() || e.file.find("..") != std::string::npos ||
          e.file[0] == '/')
        throw InputError(std::string(ctx) + ": index entry '" + e.kind + "/" + e.name + "' is malformed");
      index.entries.push_back(std::move(e));
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string(ctx) + ": /index is not a valid index (" + e.what() + ")");
  }
  return index;
}

void write_root(const fs::path& path, const Index& index) {
  const std::string ctx = path.filename().string();
  {
    h5::Id fapl(h5::check(H5Pcreate(H5P_FILE_ACCESS), ctx, "H5Pcreate"));
    h5::check(H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG), ctx, "H5Pset_fclose_degree");
    h5::Id f(h5::check(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl), ctx, "cannot create the root"));
    h5::write_attr(f, "specula_format", std::string_view("specula-store"), ctx);
    h5::write_attr(f, "format_version", 2LL, ctx);
    h5::write_attr(f, "specula_version", std::string_view(SPECULA_VERSION), ctx);
    h5::write_attr(f, "created_utc", std::string_view(index.created_utc), ctx);
    h5::write_attr(f, "generation", index.generation, ctx);
    h5::write_attr(f, "data_dir", std::string_view(index.data_dir), ctx);
    nlohmann::json j = {{"objects", nlohmann::json::array()}};
    std::string group;
    h5::Id g;
    for (const auto& e : index.entries) {
      if (e.kind != group) {
        group = e.kind;
        g = h5::Id(h5::check(H5Gcreate2(f, ("/" + group).c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
                             "cannot create /" + group));
      }
      const std::string target = index.data_dir + "/" + e.file, object = "/" + e.kind + "/" + e.name;
      h5::check(H5Lcreate_external(target.c_str(), object.c_str(), g, e.name.c_str(), H5P_DEFAULT, H5P_DEFAULT), ctx,
                "cannot link " + object);
      j["objects"].push_back({{"kind", e.kind},
                              {"name", e.name},
                              {"file", e.file},
                              {"bytes", e.bytes},
                              {"crc32", hex32(e.crc32)},
                              {"generation", e.generation}});
    }
    const std::string text = j.dump();
    h5::Id type(h5::check(H5Tcopy(H5T_C_S1), ctx, "H5Tcopy"));
    h5::check(H5Tset_size(type, H5T_VARIABLE), ctx, "H5Tset_size");
    h5::check(H5Tset_cset(type, H5T_CSET_UTF8), ctx, "H5Tset_cset");
    h5::Id space(h5::check(H5Screate(H5S_SCALAR), ctx, "H5Screate"));
    h5::Id ds(h5::check(H5Dcreate2(f, "index", type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
                        "cannot create /index"));
    const char* p = text.c_str();
    h5::check(H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, &p), ctx, "cannot write /index");
    h5::write_attr(ds, "format", std::string_view("json"), ctx);
  }
  sync_path(path);
}

std::uint32_t file_crc32(const fs::path& path, std::uint64_t& bytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw LibraryError(os_error(path, "cannot open"));
  std::vector<unsigned char> buf(4 << 20);
  std::uint32_t crc = 0;
  bytes = 0;
  for (;;) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string msg = os_error(path, "cannot read");
      ::close(fd);
      throw LibraryError(msg);
    }
    if (n == 0) break;
    crc = libdeflate_crc32(crc, buf.data(), std::size_t(n));
    bytes += std::uint64_t(n);
  }
  ::close(fd);
  return crc;
}

void sync_path(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) {
    if (directory) return;
    throw LibraryError(os_error(path, "cannot open to flush"));
  }
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0 && !directory) throw LibraryError(os_error(path, "cannot flush to disk"));
}

void create_directories_synced(const fs::path& dir) {
  if (fs::is_directory(dir)) return;
  create_directories_synced(dir.parent_path().empty() ? fs::path(".") : dir.parent_path());
  if (::mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) throw LibraryError(os_error(dir, "cannot create directory"));
  sync_path(dir.parent_path().empty() ? fs::path(".") : dir.parent_path(), true);
}

FileLock::FileLock(const fs::path& path, bool wait) : path_(path) {
  for (;;) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw LibraryError(os_error(path, "cannot open lock file"));
    int rc;
    while ((rc = ::flock(fd, LOCK_EX | (wait ? 0 : LOCK_NB))) != 0 && errno == EINTR) {}
    if (rc != 0) {
      const int saved = errno;
      ::close(fd);
      if (!wait && saved == EWOULDBLOCK) return;
      errno = saved;
      throw LibraryError(os_error(path, "cannot lock"));
    }
    // A lock file unlinked by its previous holder is no lock: take the one now at the path.
    struct stat held {
    }, now{};
    if (::fstat(fd, &held) == 0 && ::stat(path.c_str(), &now) == 0 && held.st_ino == now.st_ino &&
        held.st_dev == now.st_dev) {
      fd_ = fd;
      return;
    }
    ::close(fd);
  }
}

FileLock::FileLock(FileLock&& o) noexcept : path_(std::move(o.path_)), fd_(o.fd_) { o.fd_ = -1; }

FileLock& FileLock::operator=(FileLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(o.path_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);
}

void FileLock::remove() {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());
  ::close(fd_);
  fd_ = -1;
}

Transaction::Transaction(const fs::path& data) {
  create_directories_synced(data / "tx");
  std::random_device rd;
  std::mt19937_64 rng((std::uint64_t(rd()) << 32) ^ rd() ^ std::uint64_t(::getpid()));
  for (;;) {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
    id_ = buf;
    const fs::path p = data / "tx" / (id_ + ".lock");
    const int fd = ::open(p.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) {
      if (errno == EEXIST) continue;
      throw LibraryError(os_error(p, "cannot create the transaction's lock file"));
    }
    ::close(fd);
    lock_ = FileLock(p, true);
    return;
  }
}

std::string object_file(std::string_view kind, std::string_view name, std::string_view tx) {
  std::string stem(name);
  if (stem.size() > 160) {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a keeps long names unique within the file-name limit
    for (char c : name) h = (h ^ std::uint8_t(c)) * 1099511628211ull;
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    stem = stem.substr(0, 140) + "~" + buf;
  }
  return "objects/" + std::string(kind) + "/" + stem + "@" + std::string(tx) + ".h5";
}

ReaderLock::ReaderLock(const fs::path& data, long long generation) {
  const int fd = ::open(readers_path(data).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;
  struct flock fl {};
  fl.l_type = F_RDLCK;
  fl.l_whence = SEEK_SET;
  fl.l_start = off_t(generation);
  fl.l_len = 1;
  if (::fcntl(fd, F_OFD_SETLK, &fl) != 0) {
    ::close(fd);
    return;
  }
  fd_ = fd;
}

ReaderLock::ReaderLock(ReaderLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }

ReaderLock& ReaderLock::operator=(ReaderLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

ReaderLock::~ReaderLock() {
  if (fd_ >= 0) ::close(fd_);
}

void append_garbage(const fs::path& data, const std::vector<Garbage>& more) {
  if (more.empty()) return;
  auto list = read_garbage(data);
  list.insert(list.end(), more.begin(), more.end());
  write_garbage(data, list);
}

std::size_t transactions_in_flight(const fs::path& data, std::string_view own) {
  std::size_t n = 0;
  std::error_code ec;
  for (const auto& d : fs::directory_iterator(data / "tx", ec)) {
    const std::string f = d.path().filename().string();
    if (!f.ends_with(".lock")) continue;
    const std::string tx = f.substr(0, f.size() - 5);
    if (tx != own && tx_alive(data, tx)) ++n;
  }
  return n;
}

Reclaimed collect(const fs::path& root, const fs::path& data, const Index& current, bool orphans) {
  Reclaimed r;
  const auto list = read_garbage(data);
  std::set<std::string> referenced;
  for (const auto& e : current.entries) referenced.insert(e.file);
  std::vector<Garbage> keep;
  std::set<std::string> listed;
  auto remove_file = [&](const fs::path& p) {
    const std::uint64_t bytes = file_size_or_zero(p);
    if (::unlink(p.c_str()) == 0) {
      ++r.files;
      r.bytes += bytes;
    }
  };
  for (const auto& g : list) {
    if (referenced.count(g.file) || !listed.insert(g.file).second) continue;
    if (readers_in(data, g.from, g.to)) {
      keep.push_back(g);
      ++r.in_use;
      continue;
    }
    remove_file(data / g.file);
  }
  if (orphans) {
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(data / "objects", ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      if (!it->is_regular_file()) continue;
      const std::string rel = fs::relative(it->path(), data).string();
      if (referenced.count(rel) || listed.count(rel)) continue;
      if (tx_alive(data, tx_of(it->path().filename().string()))) continue;
      remove_file(it->path());
    }
    for (const auto& d : fs::directory_iterator(data / "tx", ec)) {
      const std::string f = d.path().filename().string();
      if (!f.ends_with(".lock")) continue;
      FileLock stale(d.path(), false);
      if (stale.held())
        stale.remove();
      else
        ++r.in_flight;
    }
    // Roots of commits that died before their rename.
    const fs::path parent = root.parent_path().empty() ? fs::path(".") : root.parent_path();
    const std::string prefix = root.filename().string() + ".commit-";
    for (const auto& d : fs::directory_iterator(parent, ec)) {
      const std::string f = d.path().filename().string();
      if (!f.starts_with(prefix) || !d.is_regular_file()) continue;
      if (!tx_alive(data, f.substr(prefix.size()))) remove_file(d.path());
    }
  }
  if (keep.size() != list.size()) write_garbage(data, keep);
  return r;
}

void claim_data_dir(const fs::path& root, const fs::path& data) {
  const fs::path owner_file = data / "owner";
  const std::string me = root.filename().string();
  std::string owner;
  {
    std::ifstream in(owner_file);
    std::getline(in, owner);
  }
  if (owner == me) return;
  if (!owner.empty()) {
    const fs::path other = (root.parent_path().empty() ? fs::path(".") : root.parent_path()) / owner;
    std::error_code ec;
    if (fs::exists(other, ec) && !fs::equivalent(other, root, ec)) {
      bool shares = false;
      const hid_t f = H5Fopen(other.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      if (f >= 0) {
        h5::Id file(f);
        shares =
            h5::has_attr(file, "data_dir") && h5::read_string_attr(file, "data_dir", owner) == data.filename().string();
      }
      H5Eclear2(H5E_DEFAULT);
      if (shares)
        throw InputError(me + ": its data directory " + data.filename().string() + " belongs to " + owner + "; " + me +
                         " is a copy of that root file alone, and writing through it would corrupt both stores. Copy a "
                         "store as its root and directory together, into another folder");
    }
  }
  const fs::path tmp = data / ("owner.tmp-" + std::to_string(::getpid()));
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << me << '\n';
    if (!out) throw LibraryError(os_error(tmp, "cannot write"));
  }
  if (::rename(tmp.c_str(), owner_file.c_str()) != 0) throw LibraryError(os_error(owner_file, "cannot write"));
}

void crash_point(std::string_view point) {
  static const char* at = std::getenv("SPECULA_TEST_CRASH_AT");
  if (at && point == at) ::kill(::getpid(), SIGKILL);
}

}  // namespace specula::store::layout
