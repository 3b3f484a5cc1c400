#pragma once
// Inside store/ only: what a StoreWriter transaction holds (its objects' open data files, removals, the committed
// state it started from).
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "specula/store/detail/objects.h"

namespace specula::store {

/// What a StoreWriter transaction holds.
struct WriterState {
  struct Pending {
    std::string kind, name, file;                     // file: relative to the data directory
    h5::Id h5;                                        // open until the object is complete
    std::size_t rows_expected = 0, rows_written = 0;  // images filled by write_image_rows
    std::vector<bool> row_done;
    std::uint64_t valid = 0;
    bool replace = false;  // may replace a committed object of its name (the options' replace when begun)
  };
  std::filesystem::path root, data;
  layout::Index base;  // the committed state when the transaction began
  bool created_data = false;
  std::optional<layout::Transaction> tx;
  std::vector<Pending> pending;
  std::vector<std::pair<std::string, std::string>> removals;
  bool committed = false;

  Pending* find(std::string_view kind, std::string_view name) {
    for (auto& p : pending)
      if (p.kind == kind && p.name == name) return &p;
    return nullptr;
  }
  const Pending* find(std::string_view kind, std::string_view name) const {
    for (auto& p : pending)
      if (p.kind == kind && p.name == name) return &p;
    return nullptr;
  }
  void close(std::string_view kind, std::string_view name) {
    if (Pending* p = find(kind, name)) p->h5 = h5::Id();
  }
  void drop(std::string_view kind, std::string_view name) {
    for (auto it = pending.begin(); it != pending.end(); ++it)
      if (it->kind == kind && it->name == name) {
        it->h5 = h5::Id();
        H5Eclear2(H5E_DEFAULT);
        std::error_code ec;
        std::filesystem::remove(data / it->file, ec);
        pending.erase(it);
        return;
      }
  }
};

}  // namespace specula::store
