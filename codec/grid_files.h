#pragma once
// Several grid exchange files (docs/grid-format.md) that belong together, e.g. a reconstruction and its confidence
// (docs/prior.md): all written, or none. Implemented beside write_grid_file (codec/spectral_grid.cpp).
#include <filesystem>
#include <span>
#include <utility>

#include "specula/store/grid.h"

namespace specula::codec {

/// Writes each (path, grid) as write_grid_file does, all or none: every file goes to a temporary first, and only
/// when all are written are they renamed into place (the first last); a failure removes those already renamed.
void write_grid_files(std::span<const std::pair<std::filesystem::path, const store::Grid*>> files);

}  // namespace specula::codec
