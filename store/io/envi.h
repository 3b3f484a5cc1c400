#pragma once
// ENVI raster (.hdr + raw binary): bsq, bil, bip; data types 1, 2, 3, 4, 5, 12; either byte order.
// ENVI spectral libraries (file type = ENVI Spectral Library, usually a .sli data file): samples = bands,
// lines = spectra, one spectrum per line, names from 'spectra names'.
// A bad band list ('bbl', one 0/1 per band) drops the bands marked 0, with their wavelengths and fwhm, unless
// the caller passes honour_bbl = false. Wavelength lists may be unsorted (ENVI allows it): the bands are sorted by
// wavelength, values and fwhm with them; a wavelength listed twice is an InputError.
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "specula/store/cube.h"

namespace specula::store {

enum class Interleave { bsq, bil, bip };

/// The fields of an ENVI header that specula uses.
struct EnviHeader {
  std::size_t samples = 0, lines = 0, bands = 0;
  std::size_t header_offset = 0;
  int data_type = 0;  ///< 1 u8, 2 i16, 3 i32, 4 f32, 5 f64, 12 u16
  Interleave interleave = Interleave::bsq;
  int byte_order = 0;              ///< 0 little endian, 1 big endian
  std::vector<double> wavelength;  ///< as written in the header
  std::string wavelength_units;    ///< "nanometers", "micrometers", ... (empty if absent)
  std::vector<double> fwhm;
  std::optional<double> data_ignore_value;
  std::vector<std::string> band_names;
  std::string description;
  std::string file_type;                   ///< e.g. "ENVI Standard", "ENVI Spectral Library" (empty if absent)
  std::vector<std::string> spectra_names;  ///< libraries: one per spectrum (line)
  std::vector<bool> bbl;                   ///< empty, or one per band (per sample for libraries): false = bad band

  /// True for file type = ENVI Spectral Library (samples are bands, lines are spectra).
  bool is_library() const;
};

/// Parses header text; throws InputError prefixed with `filename` naming the bad or missing field.
EnviHeader parse_envi_header(std::string_view text, const std::string& filename);
/// Reads an ENVI image from its .hdr or data file (wavelengths to nm and sorted ascending with their bands, never
/// resampled; ignore value masked; bbl-bad bands dropped);
/// `fallback` is used when the header has no wavelengths (one per band in the file).
/// `honour_bbl` false keeps the bands the header's bbl marks bad.
Cube read_envi(const std::filesystem::path& path, const WavelengthGrid& fallback = {}, bool honour_bbl = true);
/// Reads an ENVI spectral library (.sli/.hdr) as a collection: names kept, wavelengths to nm and sorted ascending
/// (values permuted with them), bbl-bad bands dropped unless `honour_bbl` is false, `fallback` (one per sample, nm)
/// used when the header has no wavelengths; InputError naming the file.
Collection read_envi_library(const std::filesystem::path& path, bool honour_bbl = true,
                             const WavelengthGrid& fallback = {});
/// True when the ENVI header beside or at `path` says file type = ENVI Spectral Library (false if unreadable).
bool is_envi_library(const std::filesystem::path& path);
/// Writes `cube` as float32 little-endian ENVI (.hdr beside `data_path`), masked pixels set to the ignore value -9999.
void write_envi(const std::filesystem::path& data_path, const Cube& cube, Interleave interleave = Interleave::bsq);

}  // namespace specula::store
