#pragma once
// A resampled grid corrected by its own samples: each sample's residual against the grid looked up where the sample
// lies, taken in the log domain of the prior's judge, averaged over a small box of cells and multiplied back in.
#include <array>
#include <cstddef>
#include <nlohmann/json_fwd.hpp>
#include <span>

#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// Settings of the correction by the samples' log residuals (docs/prior.md).
struct LogResidualOptions {
  int radius = 1;  ///< the residuals of the cells within radius on each index axis are averaged, in [0, 10]
  int passes = 1;  ///< corrections in turn, each against the grid the one before left, in [1, 10]
  /// the means at the lowest theta_d row the boxes reach carried down, in each (theta_h, phi_d) column, into the
  /// unseen retro band below it (the theta_d rows under the samples' lowest less radius)
  bool into_retro_band = false;
  /// theta_h rows [ring_from[d], ring_rows) of each theta_d row d take the mean over their whole phi_d ring of the
  /// boxes (the samples within radius on theta_h and theta_d, any phi_d): round the peak an isotropic BRDF hardly
  /// varies with phi_d (acquire/peak_rows.h); in [0, kMerlThetaH)
  int ring_rows = 0;
  std::array<int, brdf::kMerlThetaD> ring_from{};  ///< per theta_d row, the first theta_h row of the rings
  /// the residuals' RMS measured again after the passes (LogResidualStats::rms_after): one more pass over the samples
  bool measure_after = true;
};

/// What one correction did.
struct LogResidualStats {
  std::size_t samples = 0;          ///< samples whose residual was taken (in each pass)
  std::size_t corrected_cells = 0;  ///< valid cells with data and a sample within the box
  double rms_before = 0;            ///< RMS over samples and bands of the residuals against the grid as given
  double rms_after = 0;             ///< the same against the grid as the passes leave it (0 unless measure_after)
  int carried_rows = 0;             ///< theta_d rows of the retro band the means were carried into
  double seconds = 0;
};

/// Every cell of grid (bands x kMerlCells, < 0 no data) with data and at least one sample's cell within o.radius on
/// each index axis (phi_d wrapping) becomes (exp(m) (v cc + eps) - eps) / cc, at least 0, with cc = cos theta_i cos
/// theta_o at its centre and m per band the mean over those samples of ln((s cc_s + eps) / (g cc_s + eps)): s the
/// sample's value, cc_s its cosines, g the grid looked up trilinearly at it (brdf::merl_trilinear; corners without
/// data left out). Samples below the horizon, with a negative or non-finite value or no grid data around are left
/// out. In the theta_h rows [o.ring_from[d], o.ring_rows) of theta_d row d the box spans every phi_d. With
/// o.into_retro_band, the cells of the theta_d rows below the lowest one the boxes reach (the samples' lowest row less
/// radius) take the mean of that row in their (theta_h, phi_d) column. o.passes times, each pass's residuals taken
/// against the grid the pass before left. eps > 0 (1/sr). The same for any thread count. UsageError on sizes or
/// settings; progress shown, Interrupted between blocks of samples.
LogResidualStats correct_by_log_residuals(const brdf::SampleSource& src, const LogResidualOptions& o, double eps,
                                          std::span<float> grid);

/// What `resample --json` reports of a correction: radius, passes, ring_rows, carried_rows, samples, corrected_cells,
/// rms_before, rms_after, seconds.
nlohmann::ordered_json log_residuals_json(const LogResidualStats& st, const LogResidualOptions& o);

}  // namespace specula::acquire
