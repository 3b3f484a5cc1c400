#pragma once
// What a reconstruction with a prior (acquire/prior_resample.h) leaves: the BRDF grid and, beside it, its per-cell
// confidence as a one-band grid (docs/prior.md), written to a store together in one transaction.
#include <filesystem>
#include <span>
#include <string>

#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// The confidence grid's name beside grid `name` in a store: "NAME.confidence".
std::string confidence_name(const std::string& name);
/// The confidence file beside exchange file `path`: X.confidence.spgrid beside X.spgrid.
std::filesystem::path confidence_path(const std::filesystem::path& path);

/// Per-cell confidence (kMerlCells values, -1 below the horizon) as a one-band grid, units "confidence"; its one
/// wavelength is the middle band of `bands` (a grid names its bands; confidence has none). UsageError on size.
store::Grid confidence_grid(std::span<const float> confidence, const WavelengthGrid& bands);

/// Adds grid `name` and its confidence (confidence_name(name)) to the transaction `out`: both appear at
/// out.commit(), or neither.
void add_prior_grids(store::StoreWriter& out, const std::string& name, const store::Grid& grid,
                     const store::Grid& confidence);

}  // namespace specula::acquire
