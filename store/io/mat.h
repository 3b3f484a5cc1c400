#pragma once
// MATLAB .mat (v5 and v7.3) through libmatio: the layouts of labs and public databases.
//
// Wavelength variable: the first variable whose name is, case-insensitively, `wavelength`, `wavelengths`,
// `bands`, `wl` or `lambda` and which is a numeric vector. Values all in [0.2, 20] and not all integers are
// micrometres and become nm (x1000); anything else is kept as nm. A vector holding exactly 1, 2, ..., B is
// band numbering, not wavelengths, and counts as absent. An unsorted vector is sorted with the bands (a
// wavelength listed twice is an InputError). A usable file vector wins over the `wavelengths`
// argument; without one the argument is the grid, and without either the readers throw one InputError
// asking for the `wavelengths` option.
//
// Cube variable when `var` is empty: the only 3-D numeric variable, else the first present of `ref`
// (Harvard), `rad` (ICVL), `cube` (ARAD-1K), `reflectances` (Foster et al.), `data`; several other 3-D
// candidates throw InputError listing them. Without a 3-D variable, scalars `nRow` and `nCol` mark an
// unmixing benchmark (Jasper Ridge, Urban, Samson) whose matrix is `Y` (else the only 2-D variable with a
// dimension nRow*nCol).
//
// Dimension order (as matio reports the MATLAB dims, also for v7.3 where it undoes HDF5's reversal):
// rows x cols x bands, unless the band count (of the wavelength vector, else of the argument) equals dim 0
// and not dim 2: then bands x rows x cols. A 2-D nRow/nCol matrix is bands x pixels, or pixels x bands when
// dim 0 is nRow*nCol; pixel p is MATLAB column-major, p = row + nRow * col (the benchmarks' own
// reshape(Y', nRow, nCol, B)). A kept-band list `SlectBands`/`SelectBands` (1-based) picks the rows'
// wavelengths out of a longer `wavelengths` argument (the full sensor grid).
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "specula/store/cube.h"

namespace specula::store {

/// What a .mat file holds: an image (3-D cube or nRow/nCol matrix) or a spectral library (2-D spectra).
enum class MatKind { image, collection };

/// Decides image or collection for `var` (empty: detect): collection when the only data is a 2-D matrix
/// one of whose dimensions equals the length of the file's wavelength vector and there are no nRow/nCol.
MatKind mat_kind(const std::filesystem::path& path, const std::string& var = {});

/// Bytes reading `path` needs at most: every numeric variable in its own class plus as float32 (from the headers only).
std::uint64_t mat_decoded_bytes(const std::filesystem::path& path);

/// Reads the cube variable `var` (empty: detect, see above) as a Cube with an optional 2-D mask variable
/// (nonzero = valid) and wavelengths from the file, else `wavelengths`; throws InputError naming the file.
Cube read_mat(const std::filesystem::path& path, const std::string& var, const std::optional<std::string>& mask_var,
              const WavelengthGrid& wavelengths);

/// Reads a spectral library: 2-D `var` (empty: `data`, else the only 2-D matrix), spectra as columns when
/// dim 0 equals the band count, else as rows; names are VAR_1, VAR_2, ...; throws InputError naming the file.
Collection read_mat_collection(const std::filesystem::path& path, const std::string& var,
                               const WavelengthGrid& wavelengths);

}  // namespace specula::store
