#pragma once
// Text spectral libraries read as collections.
//
// USGS splib07a ASCII: one spectrum per file, a title line ("splib07a Record=N: <name> ...") then one value per
// line; the wavelengths (micrometres) are a separate file of the same layout whose title names "Wavelengths".
// The deleted-point value -1.23e34 means "no data". The store rejects NaN in collections, so missing data is
// never stored: a spectrum with no valid value at all is dropped, and a band missing in any remaining spectrum is
// dropped from the whole collection together with its wavelength (both reported in TextLibrary::notes).
//
// ECOSTRESS (ex-ASTER/JPL): a header of "Key: value" lines (Name, Type, ..., X Units: Wavelength (micrometers),
// Y Units: Reflectance (percent), Number of X Values, ...) then two-column rows "wavelength value", often in
// descending wavelength order. Rows are sorted ascending (values with them), micrometres become nm and percent
// becomes a fraction; the conversions are recorded in the importer provenance. Several files form one collection
// only when their grids agree exactly.
//
// Every problem is one InputError naming the file (and line for a bad row).
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/store/cube.h"

namespace specula::store {

/// A collection read from text files, with what reading it dropped (one line each, for the caller to report).
struct TextLibrary {
  Collection collection;
  std::vector<std::string> notes;
};

/// "usgs", "usgs-wavelengths", "ecostress" or "" from the first line of `path` (never throws for a readable file).
std::string sniff_text_library(const std::filesystem::path& path);
/// Reads splib07a spectra on the grid of the `wavelengths` file into one collection (names from the titles).
TextLibrary read_usgs_spectra(std::span<const std::filesystem::path> spectra, const std::filesystem::path& wavelengths);
/// Reads ECOSTRESS spectrum files (all on one grid) into one collection in nm, ascending, units converted.
TextLibrary read_ecostress_spectra(std::span<const std::filesystem::path> files);

}  // namespace specula::store
