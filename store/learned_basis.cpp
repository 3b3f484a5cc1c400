#include "specula/store/learned_basis.h"

#include <algorithm>

namespace specula::store {

std::string selection_source(const BlockReader& reader, const Selection& selection) {
  if (!selection.collection.empty()) return "collection " + selection.collection;
  std::string source = "images";
  for (const auto& n : reader.source_names()) source += " " + n;
  return source;
}

std::string source_files(const std::vector<Store>& stores) {
  std::string files;
  for (const auto& s : stores) files += (files.empty() ? "" : " ") + s.path().string();
  return files;
}

bool holds_basis(const std::filesystem::path& output, const std::string& name) {
  if (!std::filesystem::exists(output)) return false;
  const auto bases = Store::open(output).bases();
  return std::find(bases.begin(), bases.end(), name) != bases.end();
}

void save_basis(const std::filesystem::path& output, const std::string& name, const Basis& basis, bool replace,
                const std::string& command_line) {
  StoreWriter writer(output, {.compression = {}, .replace = replace, .command_line = command_line});
  writer.add_basis(name, basis);
  writer.commit();
}

}  // namespace specula::store
