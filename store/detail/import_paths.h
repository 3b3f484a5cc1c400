#pragma once
// Inside store/ only: the path helpers that the import's input expansion (import_inputs.cpp) and its readers
// (import.cpp) share.
#include <filesystem>
#include <vector>

namespace specula::store::import_detail {

/// The .hdr that describes ENVI data file `p` (NAME.hdr or NAME.EXT.hdr), or empty.
std::filesystem::path envi_header_of(const std::filesystem::path& p);
/// The entries of directory `dir` sorted by path; throws InputError naming it when it cannot be listed.
std::vector<std::filesystem::directory_entry> sorted_entries(const std::filesystem::path& dir);

}  // namespace specula::store::import_detail
