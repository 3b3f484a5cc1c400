#pragma once
// Each sample's noise variance from the camera's noise model (docs/capture-format.md#samples): a merged rate's
// variance (RateVariance: read noise, shot noise, rounding, the exposures merged) carried through the flat-field
// division, the irradiance division and the calibration's linear recovery, to first order.
#include <Eigen/Core>
#include <filesystem>
#include <vector>

#include "specula/acquire/capture.h"
#include "specula/acquire/hdr.h"
#include "specula/acquire/spectral.h"

namespace specula::acquire {

/// The noise of the samples one light position gives.
class SampleNoise {
 public:
  /// For light `light` of cap: each channel's scene exposure series (RateVariance) and the recovery's squares.
  /// UsageError as RateVariance; InputError naming the capture for a channel without exposures.
  SampleNoise(const Capture& cap, const std::filesystem::path& dir, int light, const SpectralCalibration& s,
              const SensorNoise& noise, const HdrOptions& o);
  /// The variance per band of the spectrum recovered from pixel p's merged rates divided by scale (the flat field
  /// times the irradiance factor): sum_j R_bj^2 var(rate_j) / scale^2, the rates' variances at their merged values.
  /// The non-negative reconstruction of filter captures is left out (linear recovery).
  Eigen::VectorXd variance(const std::vector<HdrImage>& hdr, std::size_t p, double scale) const;

 private:
  std::vector<RateVariance> channels_;
  Eigen::MatrixXd recovery2_;
};

}  // namespace specula::acquire
