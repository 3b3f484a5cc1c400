#pragma once
// Held-out reflectance patches (docs/capture-format.md, format 3): a chart of patches of known reflectance imaged
// through every channel with the scene's exposure bracket, never used by calibration, whose spectra the pipeline
// recovers from the captured images exactly as it recovers a scene pixel's, to measure the recovery on spectra it
// was not fitted to (eq 4.8).
#include <Eigen/Core>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/acquire/capture.h"
#include "specula/acquire/pipeline.h"
#include "specula/store/cube.h"

namespace specula::acquire {

/// The patches of `table` (one reflectance spectrum per entry, linear between its wavelengths) laid out in a grid on a
/// width x height chart, their reflectance resampled onto `bands`. InputError naming the table's source file for an
/// empty table, a negative value, wavelengths that do not cover the bands, or patches that do not fit (each needs a
/// cell of 8 x 8 pixels).
std::vector<HoldoutPatch> holdout_chart(const store::Collection& table, std::span<const double> bands, int width,
                                        int height);

/// One held-out patch's recovered reflectance against its known one.
struct HoldoutReport {
  std::string name;
  Eigen::VectorXd truth, recovered;  ///< on the bands; recovered: the mean of its usable pixels' spectra
  double rms = -1;                   ///< eq 4.8 between them; -1 when no pixel was usable
  double pixel_rms = -1;             ///< the mean over usable pixels of each pixel's own eq 4.8
  std::size_t pixels = 0;            ///< usable pixels (the patch's central half, minus rejected ones)
  std::size_t rejected = 0;          ///< pixels of the central half saturated, low in signal or non-linear
};

/// Recovers every held-out patch of the capture from its holdout images with calibration `c` as extract_samples does
/// a scene pixel (HDR merge per channel, flat correction, rejections, recovery, non-negative spectrum), over the
/// central half of each patch's region. Empty for a capture without held-out patches.
std::vector<HoldoutReport> recover_holdout(const Capture& capture, const std::filesystem::path& dir,
                                           const Calibration& c, const PipelineOptions& o);

}  // namespace specula::acquire
