#pragma once
// Relighting (reference §4.1.7): a scene seen under light L shown under light L', spectrally (eq 4.9: divide
// L out per wavelength, multiply L' in) and as an RGB camera would (eq 4.10: each channel scaled by the ratio
// of the lights' responses, von Kries), with the CIEDE2000 difference between the two.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "specula/core/colour.h"

namespace specula {

/// Both relightings of one image, as XYZ rows (one per pixel) with their scene whites, and their difference.
struct Relighting {
  RowMatrixX3f original;  ///< under the old light (radiance: scaled so its 99th-percentile Y is 1)
  RowMatrixX3f spectral;  ///< eq 4.9 under the new light
  RowMatrixX3f rgb;       ///< eq 4.10 under the new light
  Eigen::Vector3d white_from, white_to;
  std::vector<double> ciede2000;  ///< per pixel between spectral and rgb (0 where masked)
  std::size_t pixels = 0;         ///< valid pixels
  double mean_ciede2000 = 0, p95_ciede2000 = 0, max_ciede2000 = 0;
};

/// Relights spectra (N x B rows on `grid`; radiance under `from`, or reflectance when `kind` says so) to light `to`.
/// The mask (one byte per row, 0 = invalid; empty = all valid) selects the pixels the statistics use. Throws
/// InputError when `from` is zero at a band it must be divided out of or no pixel is valid, UsageError on sizes.
Relighting relight(const Eigen::Ref<const RowMatrixXf>& spectra, const WavelengthGrid& grid, SpectrumKind kind,
                   std::span<const std::uint8_t> mask, const Eigen::VectorXd& from, const Eigen::VectorXd& to);

}  // namespace specula
