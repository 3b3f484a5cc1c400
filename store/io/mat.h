#pragma once
// MATLAB .mat (v5 and v7.3) through libmatio.
#include <filesystem>
#include <optional>
#include <string>

#include "specula/store/cube.h"

namespace specula::store {

/// Reads a 3-D numeric variable `var` (rows x cols x bands, MATLAB's column-major order) as a Cube, and
/// optionally a 2-D mask variable (nonzero = valid). Wavelengths come from a variable named "wavelengths"
/// or "bands" when present, else from `wavelengths`; throws InputError naming the file and the variable.
Cube read_mat(const std::filesystem::path& path, const std::string& var,
              const std::optional<std::string>& mask_var, const WavelengthGrid& wavelengths);

}  // namespace specula::store
