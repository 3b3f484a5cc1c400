#pragma once
// ENVI raster (.hdr + raw binary): bsq, bil, bip; data types 1, 2, 3, 4, 5, 12; either byte order.
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
  int data_type = 0;          ///< 1 u8, 2 i16, 3 i32, 4 f32, 5 f64, 12 u16
  Interleave interleave = Interleave::bsq;
  int byte_order = 0;         ///< 0 little endian, 1 big endian
  std::vector<double> wavelength;       ///< as written in the header
  std::string wavelength_units;         ///< "nanometers", "micrometers", ... (empty if absent)
  std::vector<double> fwhm;
  std::optional<double> data_ignore_value;
  std::vector<std::string> band_names;
  std::string description;
};

/// Parses header text; throws InputError prefixed with `filename` naming the bad or missing field.
EnviHeader parse_envi_header(std::string_view text, const std::string& filename);
/// Reads an ENVI image from its .hdr or data file (wavelengths to nm, ignore value masked); `fallback` is used when the header has no wavelengths.
Cube read_envi(const std::filesystem::path& path, const WavelengthGrid& fallback = {});
/// Writes `cube` as float32 little-endian ENVI (.hdr beside `data_path`), masked pixels set to the ignore value -9999.
void write_envi(const std::filesystem::path& data_path, const Cube& cube, Interleave interleave = Interleave::bsq);

}  // namespace specula::store
