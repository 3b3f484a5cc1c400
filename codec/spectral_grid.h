#pragma once
// Spectral BRDF grids (store::Grid: B bands on the MERL grid) outside the store: the standalone exchange file
// of docs/grid-format.md, and export to an RGB MERL .binary through the CIE colour-matching functions.
#include <Eigen/Core>
#include <filesystem>

#include "specula/codec/merl.h"
#include "specula/core/cie.h"
#include "specula/store/grid.h"

namespace specula::codec {

/// Magic bytes that open a grid exchange file.
inline constexpr char kGridMagic[8] = {'S', 'P', 'E', 'C', 'G', 'R', 'I', 'D'};
/// Version of the exchange file this specula writes and the newest it reads.
inline constexpr std::uint32_t kGridFileVersion = 1;
/// Most bands an exchange file may declare.
inline constexpr std::uint32_t kGridMaxBands = 1024;

/// Bytes of an exchange file holding `bands` bands: 40-byte header, wavelengths, values, CRC-32.
std::uint64_t grid_file_bytes(std::size_t bands);

/// Writes `grid` as an exchange file (docs/grid-format.md) through a temporary renamed over `path`.
/// Throws UsageError if the values do not match bands x 90 x 90 x 180.
void write_grid_file(const std::filesystem::path& path, const store::Grid& grid);
/// Reads an exchange file, validating magic, version, dimensions, scale, wavelengths, size, values and CRC;
/// throws InputError naming the file and the offending field.
store::Grid read_grid_file(const std::filesystem::path& path);

/// The 3 x B matrix taking a spectral BRDF (1/sr per band) to linear sRGB under `illuminant` (B values):
/// CIE XYZ by the CMFs (SpectrumToXyz, reflectance), Bradford-adapted from the illuminant's white to sRGB's
/// D65 white, then the sRGB matrix. A spectrally flat BRDF f maps to (f, f, f).
Eigen::Matrix<double, 3, Eigen::Dynamic> rgb_weights(const WavelengthGrid& grid, const Eigen::VectorXd& illuminant,
                                                     Observer observer = Observer::cie1931_2deg);

/// An RGB MERL BRDF made from a spectral grid, and how many channel values were negative (out of the sRGB
/// gamut) and clamped to 0, since MERL reads negative as no data.
struct RgbExport {
  MerlBrdf brdf;
  std::size_t clamped = 0;
};
/// RGB = weights * (scale * spectrum) at every cell with data in all bands; cells with a negative band get no data.
RgbExport grid_to_merl(const store::Grid& grid, const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights);

}  // namespace specula::codec
