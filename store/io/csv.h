#pragma once
// CSV spectral tables.
#include <filesystem>

#include "specula/store/cube.h"

namespace specula::store {

/// Reads a spectral table into a collection. Accepted layouts: a header row whose numeric cells are the
/// wavelengths (a leading non-numeric "name" column is optional) and one spectrum per row; or a header-less
/// file whose rows are "name, v1, ..." with wavelengths given by `wavelengths`; or the transposed layout
/// (first column wavelengths, one spectrum per column, header = names). Wavelengths listed unsorted are sorted with
/// their values. Throws InputError with file:line (a wavelength listed twice, a bad cell).
Collection read_csv_collection(const std::filesystem::path& path, const WavelengthGrid& wavelengths = {});
/// Writes a collection as CSV: header "name,<nm>,..." and one row per spectrum; atomic.
void write_csv_collection(const std::filesystem::path& path, const Collection& collection);

}  // namespace specula::store
