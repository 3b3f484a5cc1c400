#pragma once
// What every learned basis shares, whatever learned it: what it was learned from (its source and provenance),
// where it goes (a name checked before hours of work) and the one transaction that saves it.
#include <filesystem>
#include <string>
#include <vector>

#include "specula/store/basis.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::store {

/// What a basis learned from `reader` records as its source: "collection NAME", or "images" and the names read.
std::string selection_source(const BlockReader& reader, const Selection& selection);
/// The stores' paths separated by spaces, as a learned basis's provenance records them.
std::string source_files(const std::vector<Store>& stores);
/// Whether the store `output` exists and holds a basis called `name` (checked before hours of work).
bool holds_basis(const std::filesystem::path& output, const std::string& name);
/// Saves `basis` as `name` in the store `output` in one transaction (created if missing; an existing basis of that
/// name replaced only with `replace`), recording `command_line`.
void save_basis(const std::filesystem::path& output, const std::string& name, const Basis& basis, bool replace,
                const std::string& command_line);

}  // namespace specula::store
