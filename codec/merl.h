#pragma once
// RGB BRDFs in the MERL database's .binary format (Matusik et al. 2003), read and written exactly as the
// database stores them: three int32 dimensions (90, 90, 180), then the red, green and blue planes of
// 90 x 90 x 180 float64 in the cell order of core/brdf_geometry.h, little-endian. A stored value times the
// channel's scale (1/1500, 1.15/1500, 1.66/1500) is the BRDF in 1/sr; a negative value means no data.
#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <vector>

#include "specula/core/brdf_geometry.h"

namespace specula::codec {

/// Per-channel scales of BRDFRead.cpp (RED_SCALE, GREEN_SCALE, BLUE_SCALE).
inline constexpr std::array<double, 3> kMerlScale = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};
/// Bytes of a MERL file: 12-byte header and three planes of float64.
inline constexpr std::size_t kMerlFileBytes = 12 + 3 * brdf::kMerlCells * sizeof(double);

/// An RGB BRDF on the MERL grid, holding the stored (unscaled) values so that files round-trip bit for bit.
struct MerlBrdf {
  /// Three planes of brdf::kMerlCells stored values: R, then G, then B.
  std::vector<double> raw = std::vector<double>(3 * brdf::kMerlCells, -1.0);

  /// Stored value of `channel` (0 R, 1 G, 2 B) at cell index `cell`.
  double stored(int channel, std::size_t cell) const { return raw[std::size_t(channel) * brdf::kMerlCells + cell]; }
  /// The BRDF (1/sr) of `channel` at `cell`: stored value times the channel's scale (negative: no data).
  double value(int channel, std::size_t cell) const { return stored(channel, cell) * kMerlScale[std::size_t(channel)]; }
  /// Sets `cell` to the BRDF values rgb (1/sr), dividing by the scales.
  void set(std::size_t cell, const Eigen::Vector3d& rgb);
  /// Every value with data times its channel's scale (stored values to 1/sr); no-data values stay as they are.
  void scale();
  /// Every value with data divided by its channel's scale (1/sr to stored values), the inverse of scale().
  void unscale();
  /// True when all three channels of `cell` hold data (are not negative).
  bool has_data(std::size_t cell) const;
  /// BRDFRead.cpp's lookup_brdf_val: the scaled RGB of the cell holding the standard angles a (negative: no data);
  /// throws UsageError on non-finite angles.
  Eigen::Vector3d lookup(const brdf::StdAngles& a) const;
};

/// Reads a MERL .binary; throws InputError naming the file and, for a wrong size, the size found and the size
/// expected; for wrong dimensions, the dimensions found; for NaN or Inf, the channel and cell.
MerlBrdf read_merl(const std::filesystem::path& path);
/// Writes `brdf` as a MERL .binary through a temporary file renamed over `path` when complete.
void write_merl(const std::filesystem::path& path, const MerlBrdf& brdf);

}  // namespace specula::codec
