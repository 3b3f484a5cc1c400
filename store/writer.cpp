// The write transaction: one new data file per object, claimed and created by begin(), removed unless committed.
#include <unistd.h>

#include <string>

#include "specula/core/error.h"
#include "specula/store/detail/writer_state.h"

namespace specula::store {

StoreWriter::StoreWriter(const std::filesystem::path& path, WriteOptions options)
    : target_(path), options_(std::move(options)), state_(std::make_unique<WriterState>()) {
  h5::quiet_errors();
  const std::string ctx = label();
  WriterState& st = *state_;
  st.root = path;
  if (std::filesystem::exists(path)) {
    const Store s = Store::open(path);  // validates: a specula store of a version we can write
    if (s.format_version() < 2)
      throw InputError(ctx + ": store format version " + std::to_string(s.format_version()) +
                       " (one file) is read-only in this specula; convert it in place with `specula upgrade " +
                       path.string() + "` (no copy of the data)");
    st.base = s.index();
    st.data = s.data_dir();
    layout::claim_data_dir(path, st.data);
  } else {
    const auto dir = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
    if (path.filename().empty()) throw UsageError("store path '" + path.string() + "' names no file");
    if (!std::filesystem::is_directory(dir))
      throw InputError(path.string() + ": directory " + dir.string() + " does not exist");
    st.data = layout::default_data_dir(path);
    st.base.data_dir = st.data.filename().string();
    st.base.created_utc = utc_now();
    st.created_data = !std::filesystem::exists(st.data);
  }
  layout::create_directories_synced(st.data / "objects");
  st.tx.emplace(st.data);
  if (st.created_data) layout::claim_data_dir(path, st.data);
}

StoreWriter::~StoreWriter() {
  if (!state_) return;
  WriterState& st = *state_;
  for (auto& p : st.pending) p.h5 = h5::Id();
  H5Eclear2(H5E_DEFAULT);
  std::error_code ec;
  if (!st.committed)
    for (const auto& p : st.pending) std::filesystem::remove(st.data / p.file, ec);
  if (st.tx) st.tx->end();
  // A store that was never created leaves no directory behind (rmdir fails harmlessly when others use it).
  if (!st.committed && st.created_data && !std::filesystem::exists(st.root)) {
    for (const auto kind : layout::kKinds) ::rmdir((st.data / "objects" / std::string(kind)).c_str());
    ::rmdir((st.data / "objects").c_str());
    ::rmdir((st.data / "tx").c_str());
    ::rmdir(st.data.c_str());
  }
}

std::int64_t StoreWriter::begin(const std::string& kind, const std::string& name, const std::string& what) {
  validate_name(name, what);
  if (!state_ || state_->committed) throw UsageError(label() + ": the transaction is already committed");
  WriterState& st = *state_;
  if (st.find(kind, name)) {
    if (!options_.replace)
      throw InputError(label() + ": " + what + " '" + name + "' is written twice in one transaction");
    st.drop(kind, name);
  }
  if (st.base.find(kind, name) && !options_.replace)
    throw InputError(label() + ": " + what + " '" + name +
                     "' exists already; choose another name or allow replacing it");
  const std::string rel = layout::object_file(kind, name, st.tx->id());
  layout::create_directories_synced(st.data / "objects" / kind);
  const std::string ctx = label() + ": /" + kind + "/" + name;
  h5::Id fapl = create_plist(H5P_FILE_ACCESS, ctx);
  h5::check(H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG), ctx, "H5Pset_fclose_degree");
  h5::check(H5Pset_cache(fapl, 0, 521, 16 << 20, 1.0), ctx, "H5Pset_cache");
  const auto file = st.data / rel;
  h5::Id f(h5::check(H5Fcreate(file.c_str(), H5F_ACC_EXCL, H5P_DEFAULT, fapl), ctx, "cannot create " + file.string()));
  layout::crash_point("object-created");
  h5::write_attr(f, "specula_format", std::string_view("specula-object"), ctx);
  h5::write_attr(f, "format_version", kFormatVersion, ctx);
  h5::write_attr(f, "kind", std::string_view(kind), ctx);
  h5::write_attr(f, "name", std::string_view(name), ctx);
  h5::write_attr(f, "transaction", std::string_view(st.tx->id()), ctx);
  st.pending.push_back({kind, name, rel, f});
  st.pending.back().replace = options_.replace;
  return f.get();
}

std::int64_t StoreWriter::object_file(const std::string& kind, const std::string& name, const std::string& hint) const {
  WriterState::Pending* p = state_ ? state_->find(kind, name) : nullptr;
  if (!p || !p->h5.valid()) throw UsageError(label() + ": /" + kind + "/" + name + ": " + hint);
  return p->h5.get();
}

void StoreWriter::remove(const std::string& kind, const std::string& name) {
  if (!layout::is_kind(kind)) throw UsageError(label() + ": '" + kind + "' is not a kind of object");
  if (!state_->base.find(kind, name)) throw InputError(label() + ": no " + kind + " '" + name + "' to remove");
  state_->removals.emplace_back(kind, name);
}

}  // namespace specula::store
