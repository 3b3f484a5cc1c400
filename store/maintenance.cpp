// Whole-store operations on the format-2 layout: check, garbage collection, and the upgrade from format 1.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <optional>
#include <set>

#include "specula/core/error.h"
#include "specula/core/progress.h"
#include "specula/store/detail/objects.h"
#include "specula/store/store.h"

namespace specula::store {
namespace {

namespace fs = std::filesystem;

struct Link {
  std::string file, object;
};

// The external link at `path` of `root`, or nothing when absent or of another type.
std::optional<Link> external_link(hid_t root, const std::string& path) {
  H5L_info_t info{};
  if (H5Lget_info(root, path.c_str(), &info, H5P_DEFAULT) < 0) {
    H5Eclear2(H5E_DEFAULT);
    return std::nullopt;
  }
  if (info.type != H5L_TYPE_EXTERNAL) return std::nullopt;
  std::vector<char> buf(info.u.val_size + 1, '\0');
  const char* file = nullptr;
  const char* object = nullptr;
  unsigned flags = 0;
  if (H5Lget_val(root, path.c_str(), buf.data(), buf.size(), H5P_DEFAULT) < 0 ||
      H5Lunpack_elink_val(buf.data(), info.u.val_size, &flags, &file, &object) < 0) {
    H5Eclear2(H5E_DEFAULT);
    return std::nullopt;
  }
  return Link{file ? file : "", object ? object : ""};
}

// True when the data file at `path` opens as HDF5 and holds group `object`.
bool holds(const fs::path& path, const std::string& object) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    H5Eclear2(H5E_DEFAULT);
    return false;
  }
  h5::Id file(f);
  const htri_t ok = H5Oexists_by_name(file, object.c_str(), H5P_DEFAULT);
  H5Eclear2(H5E_DEFAULT);
  return ok > 0;
}

}  // namespace

std::pair<std::string, std::string> resolve_object(const Store& store, const std::string& spec) {
  static const std::pair<std::string_view, std::string_view> aliases[] = {
      {"image", "images"},        {"collection", "collections"},   {"grid", "grids"},
      {"basis", "bases"},         {"coefficient", "coefficients"}, {"map", "coefficients"},
      {"calibration", "acquire"}, {"calibrations", "acquire"},     {"prior", "priors"}};
  std::string s = spec;
  if (!s.empty() && s[0] == '/') s = s.substr(1);
  const auto slash = s.find('/');
  std::vector<std::pair<std::string, std::string>> found;
  if (slash != std::string::npos) {
    std::string kind = s.substr(0, slash);
    for (const auto& [a, k] : aliases)
      if (kind == a) kind = k;
    if (!layout::is_kind(kind))
      throw InputError(
          store.label() + ": '" + spec + "': '" + s.substr(0, slash) +
          "' is not a kind of object (images, collections, samples, grids, bases, coefficients, acquire, priors)");
    const std::string name = s.substr(slash + 1);
    if (h5::exists(StoreAccess::root(store), "/" + kind) &&
        h5::exists(StoreAccess::root(store), "/" + kind + "/" + name))
      return {kind, name};
    throw InputError(store.label() + ": no " + kind + " object '" + name + "'");
  }
  for (const auto kind : layout::kKinds)
    if (h5::exists(StoreAccess::root(store), "/" + std::string(kind)) &&
        h5::exists(StoreAccess::root(store), "/" + std::string(kind) + "/" + s))
      found.emplace_back(kind, s);
  if (found.size() == 1) return found.front();
  if (found.empty()) throw InputError(store.label() + ": no object '" + spec + "'; `specula ls` lists them");
  std::string kinds;
  for (const auto& f : found) kinds += (kinds.empty() ? "" : ", ") + f.first + "/" + f.second;
  throw InputError(store.label() + ": '" + spec + "' names several objects (" + kinds + "); say which with KIND/NAME");
}

std::uint64_t store_bytes(const Store& store) {
  std::error_code ec;
  std::uint64_t total = fs::file_size(store.path(), ec);
  std::set<std::string> seen;
  for (const auto& e : store.index().entries)
    if (seen.insert(e.file).second) total += e.bytes;
  return total;
}

std::vector<Problem> check(const fs::path& path) {
  const Store s = Store::open(path);
  const std::string ctx = s.label();
  if (s.format_version() < 2)
    throw InputError(ctx + ": a format-1 store records no checksums; convert it with `specula upgrade " +
                     path.string() + "`, then check it");
  const layout::Index& index = s.index();
  const fs::path data = s.data_dir();
  std::vector<Problem> out;
  std::uint64_t total = 0;
  for (const auto& e : index.entries) total += e.bytes;
  Progress progress("checking " + ctx, total);
  std::map<std::string, std::pair<std::uint64_t, std::uint32_t>> verified;  // file -> (bytes, crc) as read
  for (const auto& e : index.entries) {
    const std::string what = e.kind + "/" + e.name;
    const fs::path file = data / e.file;
    auto it = verified.find(e.file);
    if (it == verified.end()) {
      std::error_code ec;
      if (!fs::is_regular_file(file, ec)) {
        out.push_back({what + ": data file " + e.file + " is missing"});
        continue;
      }
      std::uint64_t bytes = 0;
      const std::uint32_t crc = layout::file_crc32(file, bytes);
      it = verified.emplace(e.file, std::pair{bytes, crc}).first;
      progress.advance(e.bytes);
    }
    if (it->second.first != e.bytes) {
      out.push_back({what + ": data file " + e.file + " has " + std::to_string(it->second.first) +
                     " bytes, the index records " + std::to_string(e.bytes) + " (truncated or overwritten)"});
      continue;
    }
    if (it->second.second != e.crc32) {
      out.push_back({what + ": data file " + e.file + " does not match its recorded checksum (corrupt)"});
      continue;
    }
    if (!holds(file, "/" + e.kind + "/" + e.name))
      out.push_back({what + ": data file " + e.file + " does not hold /" + e.kind + "/" + e.name});
    const auto link = external_link(StoreAccess::root(s), "/" + e.kind + "/" + e.name);
    if (!link)
      out.push_back({what + ": the root has no external link for it"});
    else if (link->file != index.data_dir + "/" + e.file || link->object != "/" + e.kind + "/" + e.name)
      out.push_back({what + ": the root links it to " + link->file + ":" + link->object + ", the index to " +
                     index.data_dir + "/" + e.file});
  }
  for (const auto kind : layout::kKinds)
    for (const auto& name : h5::list(StoreAccess::root(s), "/" + std::string(kind)))
      if (!index.find(kind, name))
        out.push_back({std::string(kind) + "/" + name + ": linked from the root but not in the index"});
  return out;
}

layout::Reclaimed collect_garbage(const fs::path& path) {
  const std::string ctx = path.filename().string();
  fs::path data;
  {
    const Store s = Store::open(path);
    if (s.format_version() < 2)
      throw InputError(ctx + ": a format-1 store is one file with nothing to collect; `specula upgrade " +
                       path.string() + "` converts it");
    data = s.data_dir();
  }
  layout::claim_data_dir(path, data);
  layout::FileLock lock(data / "commit.lock", true);
  const Store s = Store::open(path);
  return layout::collect(path, data, s.index(), true);
}

void upgrade(const fs::path& path) {
  const std::string ctx = path.filename().string();
  std::string created;
  std::vector<std::pair<std::string, std::string>> objects;
  struct stat before {};
  {
    const Store s = Store::open(path);
    if (s.format_version() != 1)
      throw InputError(ctx + ": already store format version " + std::to_string(s.format_version()) +
                       "; nothing to upgrade");
    created = h5::has_attr(StoreAccess::root(s), "created_utc")
                  ? h5::read_string_attr(StoreAccess::root(s), "created_utc", ctx)
                  : utc_now();
    for (const auto kind : layout::kKinds)
      for (const auto& name : h5::list(StoreAccess::root(s), "/" + std::string(kind))) {
        validate_name(name, std::string(kind) + " name");
        objects.emplace_back(kind, name);
      }
    if (::stat(path.c_str(), &before) != 0) throw LibraryError(ctx + ": cannot stat: " + std::strerror(errno));
  }
  const fs::path data = layout::default_data_dir(path);
  layout::create_directories_synced(data / "objects" / "legacy");
  layout::Transaction tx(data);
  layout::claim_data_dir(path, data);
  const std::string rel = "objects/legacy/" + path.filename().string() + "@" + tx.id() + ".h5";
  const fs::path legacy = data / rel;
  // The format-1 file becomes the data file of every object in it: a second name for the same bytes.
  if (::link(path.c_str(), legacy.c_str()) != 0) {
    if (errno != EXDEV && errno != EPERM && errno != EOPNOTSUPP && errno != EMLINK)
      throw LibraryError(ctx + ": cannot link into " + data.string() + ": " + std::strerror(errno));
    std::error_code ec;
    if (!fs::copy_file(path, legacy, ec)) {
      fs::remove(legacy, ec);
      throw LibraryError(ctx + ": cannot copy into " + data.string() + ": " + ec.message());
    }
  }
  layout::sync_path(legacy);
  layout::sync_path(legacy.parent_path(), true);
  layout::Entry proto{"", "", rel, 0, 0, 1};
  proto.crc32 = layout::file_crc32(legacy, proto.bytes);
  {
    const int fd = ::open((data / "readers").c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, 0644);
    if (fd >= 0) ::close(fd);
  }
  layout::FileLock lock(data / "commit.lock", true);
  struct stat now {};
  if (::stat(path.c_str(), &now) != 0 || now.st_ino != before.st_ino || now.st_mtime != before.st_mtime ||
      now.st_size != before.st_size) {
    std::error_code ec;
    fs::remove(legacy, ec);
    throw InputError(ctx +
                     ": the store changed while it was being upgraded; nothing was converted, run the upgrade again");
  }
  layout::Index index;
  index.generation = 1;
  index.created_utc = created;
  index.data_dir = data.filename().string();
  for (const auto& [kind, name] : objects) {
    layout::Entry e = proto;
    e.kind = kind;
    e.name = name;
    index.entries.push_back(e);
  }
  const fs::path tmp = path.string() + ".commit-" + tx.id();
  try {
    layout::write_root(tmp, index);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    fs::remove(legacy, ec);
    throw;
  }
  layout::crash_point("upgrade-root-written");
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    std::error_code ec;
    fs::remove(tmp, ec);
    fs::remove(legacy, ec);
    throw LibraryError(ctx + ": cannot rename the new root into place: " + err);
  }
  layout::sync_path(path.parent_path().empty() ? fs::path(".") : path.parent_path(), true);
  tx.end();
}

}  // namespace specula::store
