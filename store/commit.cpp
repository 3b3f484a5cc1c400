// The commit protocol of docs/store-format.md: data files durable, merge under the commit lock, garbage logged,
// the new root renamed over the old one, then reclamation.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/detail/writer_state.h"

namespace specula::store {

namespace {

// Images written row by row are complete, or the transaction is wrong; their valid-pixel counts are recorded.
void finish_images(WriterState& st, const std::string& ctx) {
  for (auto& p : st.pending) {
    if (p.rows_expected == 0) continue;
    if (p.rows_written != p.rows_expected)
      throw UsageError(ctx + ": /images/" + p.name + ": " + std::to_string(p.rows_written) + " of " +
                       std::to_string(p.rows_expected) + " rows written; write every row before commit");
    h5::Id g = open_group(p.h5, "/images/" + p.name, ctx);
    h5::write_attr(g, "valid_pixels", static_cast<long long>(p.valid), ctx);
  }
}

// Step 1: every data file complete and durable before anything points at it; returns their index entries.
std::vector<layout::Entry> make_durable(WriterState& st, const std::string& ctx) {
  std::vector<layout::Entry> added;
  std::set<std::string> dirs;
  for (auto& p : st.pending) {
    if (p.h5.valid()) {
      h5::check(H5Fflush(p.h5, H5F_SCOPE_GLOBAL), ctx, "cannot flush " + p.file);
      p.h5 = h5::Id();
    }
    layout::Entry e{p.kind, p.name, p.file, 0, 0, 0};
    e.crc32 = layout::file_crc32(st.data / p.file, e.bytes);
    layout::sync_path(st.data / p.file);
    dirs.insert(p.kind);
    added.push_back(std::move(e));
  }
  layout::crash_point("data-written");
  for (const auto& k : dirs) layout::sync_path(st.data / "objects" / k, true);
  layout::sync_path(st.data / "objects", true);
  {
    const int fd = ::open((st.data / "readers").c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, 0644);
    if (fd >= 0) ::close(fd);
  }
  layout::sync_path(st.data, true);
  return added;
}

// The state committed at the root now (the transaction's base with no objects when the root does not exist yet).
layout::Index current_index(const WriterState& st, const std::string& ctx) {
  layout::Index cur;
  if (std::filesystem::exists(st.root)) {
    h5::Id f = open_root(st.root, ctx);
    if (!h5::has_attr(f, "format_version") || h5::read_int_attr(f, "format_version", ctx) != kFormatVersion)
      throw InputError(
          ctx + ": the store was replaced by a file of another format while this transaction ran; nothing was written");
    cur = layout::read_index(f, ctx);
    if (cur.data_dir != st.base.data_dir)
      throw InputError(ctx +
                       ": another store was created at this path while this transaction ran; nothing was written");
  } else {
    cur = st.base;
    cur.generation = 0;
    cur.entries.clear();
  }
  return cur;
}

// Step 2 (under the commit lock): `cur` with the removals and `added` merged in as generation cur.generation + 1;
// the files it stops referencing go to `garbage`.
void merge(layout::Index& cur, const WriterState& st, std::vector<layout::Entry>& added, bool replace,
           const std::string& ctx, std::vector<layout::Garbage>& garbage) {
  const long long gen = cur.generation + 1;
  auto unlink_entry = [&](std::string_view kind, std::string_view name) {
    for (auto it = cur.entries.begin(); it != cur.entries.end(); ++it)
      if (it->kind == kind && it->name == name) {
        const layout::Entry old = *it;
        cur.entries.erase(it);
        if (!cur.references(old.file)) garbage.push_back({old.file, old.generation, gen});
        return;
      }
  };
  for (const auto& [kind, name] : st.removals) unlink_entry(kind, name);
  for (auto& e : added) {
    if (cur.find(e.kind, e.name)) {
      const WriterState::Pending* pending = st.find(e.kind, e.name);
      if (!(pending ? pending->replace : replace))
        throw InputError(ctx + ": " + e.kind + "/" + e.name +
                         " was committed by another writer while this transaction ran; "
                         "nothing was written (choose another name or allow replacing it)");
      unlink_entry(e.kind, e.name);
    }
    e.generation = gen;
    cur.entries.push_back(e);
  }
  auto order = [](const layout::Entry& e) {
    return std::find(std::begin(layout::kKinds), std::end(layout::kKinds), e.kind) - std::begin(layout::kKinds);
  };
  std::sort(cur.entries.begin(), cur.entries.end(), [&](const layout::Entry& a, const layout::Entry& b) {
    return std::pair(order(a), a.name) < std::pair(order(b), b.name);
  });
  cur.generation = gen;
}

// Step 3: the garbage list first, then the new root, renamed over the old one: the commit point.
void publish(WriterState& st, const layout::Index& cur, const std::vector<layout::Garbage>& garbage,
             const std::string& ctx) {
  layout::append_garbage(st.data, garbage);
  layout::crash_point("garbage-logged");
  const std::filesystem::path tmp = st.root.string() + ".commit-" + st.tx->id();
  try {
    layout::write_root(tmp, cur);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  layout::crash_point("root-written");
  if (::rename(tmp.c_str(), st.root.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw LibraryError(ctx + ": cannot rename the new root into place: " + err);
  }
  st.committed = true;
  layout::sync_path(st.root.parent_path().empty() ? std::filesystem::path(".") : st.root.parent_path(), true);
  layout::crash_point("renamed");
}

}  // namespace

void StoreWriter::commit() {
  if (!state_ || state_->committed) throw UsageError(label() + ": StoreWriter::commit called twice");
  WriterState& st = *state_;
  const std::string ctx = label();
  finish_images(st, ctx);
  std::vector<layout::Entry> added = make_durable(st, ctx);
  layout::FileLock lock(st.data / "commit.lock", true);
  layout::crash_point("locked");
  layout::Index cur = current_index(st, ctx);
  std::vector<layout::Garbage> garbage;
  merge(cur, st, added, options_.replace, ctx, garbage);
  publish(st, cur, garbage, ctx);
  // Step 4: reclaim what no reader can see; a failure here leaves garbage for the next commit, never a lost commit.
  try {
    reclaimed_ = layout::collect(st.root, st.data, cur, layout::transactions_in_flight(st.data, st.tx->id()) == 0);
  } catch (const std::exception&) {}
  layout::crash_point("collected");
}

}  // namespace specula::store
