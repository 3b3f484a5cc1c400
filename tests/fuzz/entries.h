#pragma once
// The fuzz entry functions: one per reader, shared by the libFuzzer targets (tests/fuzz/target.cpp) and the corpus
// regression test (tests/fuzz/corpus_test.cpp). Each writes its input where the reader expects files, reads it, and
// either returns (the result passed its invariants) or throws specula::Error whose message is one line naming the
// file. A broken invariant or a message that is not one line naming the file throws std::logic_error; anything
// else thrown is the reader's own defect.
//
// Inputs holding several files (an ENVI header and its data, a USGS wavelengths file and spectra) separate them by
// kFileSeparator.
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace specula::fuzz {

/// Separates the files of one input: "<first file>\n--next file--\n<second file>...".
inline constexpr std::string_view kFileSeparator = "\n--next file--\n";

using Entry = void (*)(std::span<const std::uint8_t> input);

/// An entry function and the corpus directory (tests/fuzz/corpus/<name>) and target (<name>_fuzz) named after it.
struct Target {
  std::string_view name;
  Entry entry;
};

/// parse_envi_header on the input as header text.
void envi_header(std::span<const std::uint8_t> input);
/// An ENVI header and its data file: read_envi_library for a spectral library, else read_envi; bbl honoured and not.
void envi(std::span<const std::uint8_t> input);
/// A .mat file (v5 or v7.3): mat_kind, then read_mat or read_mat_collection with layout detection.
void mat(std::span<const std::uint8_t> input);
/// A mask: a PNG when the input starts with the PNG signature, else an ENVI header and its data file.
void mask(std::span<const std::uint8_t> input);
/// ECOSTRESS files when the first one sniffs as ECOSTRESS, else a USGS wavelengths file and spectra.
void text_library(std::span<const std::uint8_t> input);
/// A CSV spectral table.
void csv(std::span<const std::uint8_t> input);
/// A raster as a .tif through GdalRaster (3-band fallback grid), every row read in strips of 2. NaN or Inf in a valid
/// pixel is not a defect: the import's --nan policy decides about it.
void gdal(std::span<const std::uint8_t> input);
/// .spc bytes: decode_spc_coefficients, then expand_spc and spc_basis on what it accepts.
void spc(std::span<const std::uint8_t> input);
/// A .spgrid exchange file (read_grid_file). The first byte chooses the layout: odd, the rest is the file as is;
/// even, the rest is the 40-byte header then a pattern repeated to the size the header's band count needs (at most
/// 4 bands: whole files are megabytes), the CRC-32 fixed up when the byte is 0 so the values themselves are read.
void spgrid(std::span<const std::uint8_t> input);
/// A MERL .binary (read_merl). The first byte chooses the layout: odd, the rest is the file as is; even, the rest is
/// the 12-byte header then a pattern of float64 values repeated to the 35 MB a MERL file holds.
void merl(std::span<const std::uint8_t> input);

/// An RGL .bsdf: read_rgl_bsdf, then RglEvaluator at a few direction pairs (finite, non-negative values).
void rgl_bsdf(std::span<const std::uint8_t> input);
/// Keras weights of a neural BRDF (.h5) through read_nbrdf: every layer of its shape, every weight finite.
void nbrdf(std::span<const std::uint8_t> input);

/// A filter CSV (parse_filters_csv), then check_filters against 420-720 nm bands: curves in [0, 1] on increasing
/// wavelengths.
void filters_csv(std::span<const std::uint8_t> input);

/// Every target, in the order above.
const std::vector<Target>& targets();

}  // namespace specula::fuzz
