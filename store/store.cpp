#include "specula/store/store.h"

#include <sys/stat.h>

#include <cctype>
#include <ctime>
#include <string>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"
#include "specula/version.h"

namespace specula::store {

Compression Compression::parse(std::string_view spec) {
  Compression c;
  if (spec == "none") {
    c.kind = Kind::none;
    return c;
  }
  if (spec == "deflate") return c;
  if (spec.starts_with("deflate:") && spec.size() == 9 && spec[8] >= '1' && spec[8] <= '9') {
    c.level = spec[8] - '0';
    return c;
  }
  throw UsageError("compression '" + std::string(spec) + "': use none, deflate or deflate:LEVEL with LEVEL 1-9");
}

std::string Compression::describe() const {
  return kind == Kind::none ? "none" : "shuffle+deflate:" + std::to_string(level);
}

void validate_name(const std::string& name, const std::string& kind) {
  bool ok = !name.empty() && name.size() <= 255 && name[0] != '.';
  for (char c : name)
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' || c == '+');
  if (!ok)
    throw UsageError(
        kind + " name '" + name +
        "' is not allowed: use 1-255 characters of letters, digits, '_', '-', '.', '+', not starting with '.'");
}

std::string utc_now() {
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// ---------------------------------------------------------------- Store

struct Store::Snapshot {
  layout::Index index;
  layout::ReaderLock lock;
};

Store Store::open(const std::filesystem::path& path) {
  h5::quiet_errors();
  Store s;
  s.path_ = path;
  const std::string ctx = s.label();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(ctx + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw InputError(ctx + ": is a directory, not a store file");
  // A reader pins the generation it opened; a commit between opening the root and pinning it makes it try again.
  for (int attempt = 0;; ++attempt) {
    const htri_t is = H5Fis_hdf5(path.c_str());
    if (is <= 0) {
      H5Eclear2(H5E_DEFAULT);
      throw InputError(
          ctx + ": not an HDF5 file, so not a specula store (create one with `specula import` or `specula synth-db`)");
    }
    h5::Id f = open_root(path, ctx);
    if (!h5::has_attr(f, "specula_format") || h5::read_string_attr(f, "specula_format", ctx) != kFormatName)
      throw InputError(ctx + ": an HDF5 file but not a specula store (no specula_format = \"" + kFormatName +
                       "\" attribute on /); create stores with `specula import` or `specula synth-db`");
    s.version_ = h5::read_int_attr(f, "format_version", ctx);
    if (s.version_ > kFormatVersion)
      throw InputError(ctx + ": store format version " + std::to_string(s.version_) + " is newer than this specula (" +
                       SPECULA_VERSION + ") reads (up to " + std::to_string(kFormatVersion) + "); upgrade specula");
    if (s.version_ < 1) throw InputError(ctx + ": invalid store format version " + std::to_string(s.version_));
    if (s.version_ == 1) {
      s.file_ = std::make_shared<h5::Id>(std::move(f));
      return s;
    }
    auto snap = std::make_shared<Snapshot>();
    snap->index = layout::read_index(f, ctx);
    snap->lock = layout::ReaderLock(layout::data_dir(path, snap->index), snap->index.generation);
    struct stat now {};
    const auto opened = opened_inode(f, ctx);
    if (attempt < 100 && (::stat(path.c_str(), &now) != 0 || now.st_dev != opened.first || now.st_ino != opened.second))
      continue;
    s.file_ = std::make_shared<h5::Id>(std::move(f));
    s.snapshot_ = std::move(snap);
    return s;
  }
}

bool Store::stale() const {
  if (!file_) return false;
  const auto opened = opened_inode(*file_, label());
  struct stat now {};
  return ::stat(path_.c_str(), &now) != 0 || now.st_dev != opened.first || now.st_ino != opened.second;
}

const layout::Index& Store::index() const {
  static const layout::Index none;
  return snapshot_ ? snapshot_->index : none;
}

std::vector<std::string> Store::images() const { return h5::list(StoreAccess::root(*this), "/images"); }
std::vector<std::string> Store::collections() const { return h5::list(StoreAccess::root(*this), "/collections"); }
std::vector<std::string> Store::samples() const { return h5::list(StoreAccess::root(*this), "/samples"); }
std::vector<std::string> Store::grids() const { return h5::list(StoreAccess::root(*this), "/grids"); }
std::vector<std::string> Store::bases() const { return h5::list(StoreAccess::root(*this), "/bases"); }
std::vector<std::string> Store::coefficients() const { return h5::list(StoreAccess::root(*this), "/coefficients"); }

}  // namespace specula::store
