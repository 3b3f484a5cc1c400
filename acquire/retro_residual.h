#pragma once
// Whether the samples' log residuals are carried down into the unseen retro-reflection band (docs/prior.md, "The
// log residuals carried into the band, chosen from the scan"): which a material needs is decided inside the band,
// where no sample is, so the carry is rehearsed one band higher on the reach's holdout (acquire/prior_reach.h), as
// the band's weight is.
#include <cstddef>
#include <nlohmann/json_fwd.hpp>
#include <span>

#include "specula/acquire/log_residual.h"
#include "specula/acquire/prior.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// What the rehearsal found.
struct RetroResidualChoice {
  bool carried = false;      ///< the carry's error over the held band is strictly the lower
  double error_carried = 0;  ///< mean log-domain error over the held band's cells with the carry
  double error_plain = 0;    ///< the same without it
  std::size_t cells = 0;     ///< held band cells judged
  int carried_rows = 0;      ///< theta_d rows the rehearsal carried into (below the kept samples' lowest less radius)
  double seconds = 0;
};

/// `rehearsal` (bands x kMerlCells) is the blend made from `kept`, the samples without the held band's and those
/// below it (reach_holdout of acquire/prior_reach.h); it is corrected by their log residuals (o's radius and passes,
/// eps; correct_by_log_residuals) once with the carry into the rows below them and once without, and each is judged at
/// the held band's cell means `band` by blend_error (acquire/scan_holdout.h, the same eps), averaged over band's cells
/// in their order. The same for any thread count. UsageError on sizes or settings, InputError when band is empty;
/// Interrupted between blocks.
RetroResidualChoice choose_retro_residuals(const brdf::SampleSource& kept, const PriorObservations& band,
                                           std::span<const float> rehearsal, const LogResidualOptions& o, double eps);

/// The theta_d rows [0, end) whose samples can change choose_retro_residuals' result at held band cells below theta_d
/// row band_end, when the lowest row holding a usable kept sample is `lowest`: a pass corrects a cell from the samples
/// within o.radius rows of it, the carry copies row lowest - o.radius down, and each further pass reaches o.radius + 1
/// rows further through the grid's corners. Samples from row end up may be left out of `kept`.
int carry_rehearsal_rows(int band_end, int lowest, const LogResidualOptions& o);

/// What `resample --json` reports of the choice: carried, error_carried, error_plain, cells, carried_rows, seconds.
nlohmann::ordered_json retro_residual_json(const RetroResidualChoice& c);

}  // namespace specula::acquire
