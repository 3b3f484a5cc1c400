#pragma once
// One whole resample of a store's samples (`specula resample`): the bandwidth resolved (a count, or chosen by
// leave-one-out on the same k-d tree the grid is then built from), the samples put onto the MERL grid plainly,
// with a learned prior or on a fitted model, and the grid's provenance, report and summary built, ready to save.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <variant>

#include "specula/acquire/bandwidth.h"
#include "specula/acquire/cap_weight.h"
#include "specula/acquire/log_residual.h"
#include "specula/acquire/model_fit.h"
#include "specula/acquire/peak_rows.h"
#include "specula/acquire/peak_rows_choice.h"
#include "specula/acquire/prior.h"
#include "specula/acquire/prior_reach.h"
#include "specula/acquire/prior_resample.h"
#include "specula/core/brdf_resample.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// The kd-tree estimate alone; cells without support are left without data.
struct PlainMethod {};

/// A learned prior fitted to the samples and blended with the kd-tree estimate (acquire/prior_resample.h).
struct PriorMethod {
  std::string prior;  ///< STORE.h5:PRIOR
  PriorFitOptions fit;
  double confidence_reach = kPriorConfidenceReach;  ///< the reach without reach_auto
  /// given (the default): the reach is chosen by holdout (acquire/prior_reach.h); residuals need it empty
  std::optional<ReachOptions> reach_auto = ReachOptions{};
  bool residuals = false;
  bool prior_in_cap = true;
  /// given (the default) with prior_in_cap and not residuals: the kd-tree's weight in the unseen cap is chosen by
  /// rehearsal (acquire/cap_weight.h); empty: the prior alone there
  std::optional<CapWeightOptions> cap_auto = CapWeightOptions{};
  bool ceiling = true;  ///< the fit in the unseen cells bounded by the prior's ceiling (PriorResampleOptions)
  /// given (the default): the fit bounded by energy conservation (PriorResampleOptions)
  std::optional<EnergyBoundOptions> energy_bound = EnergyBoundOptions{};
  bool log_blend = true;  ///< the chosen weights of the cap and the retro band mix in the log domain (ditto)
  /// given (the default) without residuals: the blend corrected by the samples' log residuals against it
  /// (acquire/log_residual.h), in the domain of the blend's epsilon; empty: the blend as it is
  std::optional<LogResidualOptions> log_residuals = LogResidualOptions{};
  /// true (the default) with reach_auto and log_residuals: whether the log residuals are carried into the unseen
  /// retro band is chosen by the reach's rehearsal (acquire/retro_residual.h); false: log_residuals' own setting
  bool retro_residuals_auto = true;
  /// true (the default): the unseen retro band's phi_d dependence settled as reciprocity asks at theta_d = 0
  /// (settle_retro_pole, acquire/retro_band.h), after everything else
  bool retro_pole = true;
  /// true: after the pole, the unseen retro band's rows from theta_h = 22.5 degrees on scaled to the rise the prior's
  /// map predicts from the result's own shoulder (raise_retro_band, acquire/retro_rise.h); false (the default): left
  bool retro_rise = false;
  /// given (the default): how far the theta_h rows round the peak are settled in phi_d, group by group, and the log
  /// residuals' ring rows are chosen from the samples (choose_peak_rows, acquire/peak_rows_choice.h); empty: peak_rows
  std::optional<PeakRowsChoiceOptions> peak_auto = PeakRowsChoiceOptions{};
  /// without peak_auto: theta_h rows below this, from the unseen cap up, settled in phi_d as reciprocity asks of an
  /// isotropic BRDF at theta_h = 0 (settle_peak_rows, acquire/peak_rows.h), the log residuals' boxes spanning every
  /// phi_d there (LogResidualOptions::ring_rows); 0 leaves them
  int peak_rows = 0;
};

/// A Lambertian plus microfacet lobes fitted as the base, the kd-tree estimate of the residuals added near samples.
struct ModelMethod {
  ModelFitOptions fit;
  double confidence_reach = 1;
};

struct ResampleJob {
  std::string store;    ///< the store holding the samples
  std::string samples;  ///< their name
  brdf::ResampleOptions local;
  std::optional<BandwidthOptions> k_auto;  ///< given: local.k is chosen by leave-one-out over this ladder
  std::variant<PlainMethod, PriorMethod, ModelMethod> method;
};

/// What a resample made: the grid (with provenance), the confidence beside it for a prior or a model, what
/// `resample --json` reports (without the output names) and a one-line summary (without the destination).
struct ResampleOutcome {
  store::Grid grid;
  std::optional<store::Grid> confidence;
  nlohmann::ordered_json report;
  std::string summary;
};

/// UsageError naming the parameter for what no store can make right: the local options (brdf::check_options), a
/// largest gap above 180 degrees, a confidence reach outside (0, 1] or a model of other than 1 or 2 lobes.
void check_job(const ResampleJob& job);

/// Resamples job.samples of job.store as job.method says, writing nothing; the plain method with -k auto builds
/// its k-d tree once for the choice and the grid. UsageError for bad options (before any work), InputError for
/// missing samples or prior, Interrupted between blocks.
ResampleOutcome run_resample(const ResampleJob& job);

}  // namespace specula::acquire
