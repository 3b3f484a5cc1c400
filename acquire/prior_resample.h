#pragma once
// Resampling scattered samples with a learned prior (acquire/prior.h): the samples averaged per MERL cell are
// the observations the prior is fitted to (weighted by their count and their scatter, PriorWeights), the kd-tree
// estimate of core/brdf_resample.h is kept where samples are near, and the two are blended by a per-cell
// confidence c = max(0, 1 - (g / (r max_gap))^2) of the distance g from the cell centre to its nearest sample
// (config_distance, as the kd-tree's support test); every valid cell gets data. Or (residuals) the kd-tree
// estimate of the samples' residuals against the fit is added to it, scaled by c (acquire/base_resample.h).
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "specula/acquire/energy_bound.h"
#include "specula/acquire/peak_cap.h"
#include "specula/acquire/prior.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// The reach r of the kd-tree estimate in the blend when it is not chosen from the scan (acquire/prior_reach.h, the
/// default of `resample --prior`) and with the residuals: chosen on held-out NBRDF materials (docs/prior.md), where
/// the prior's fit beat the kd-tree's average except very near samples.
inline constexpr double kPriorConfidenceReach = 0.1;

struct PriorResampleOptions {
  brdf::ResampleOptions local;  ///< the kd-tree estimate
  PriorFitOptions fit;
  /// r: confidence falls to 0 at r * local.max_gap from the nearest sample (0 < r <= 1)
  double confidence_reach = kPriorConfidenceReach;
  /// given (kMerlThetaH values, each in (0, 1]): the reach of the cells of each theta_h row instead of
  /// confidence_reach (chosen per group of rows by prior_reach.h); the residuals form ignores it
  std::vector<double> reach_by_theta_h;
  /// false: c * local + (1 - c) * prior; true: max(0, prior + c * local estimate of the residuals against the
  /// prior fit) (acquire/base_resample.h, as --model)
  bool residuals = false;
  /// true: cells of the unseen cap round the specular peak (acquire/peak_cap.h) take the prior alone (confidence 0),
  /// or as cap_weight says, in the blend; false: the kd-tree estimate as elsewhere. The residuals form ignores it.
  bool prior_in_cap = true;
  /// given: cells of the unseen retro-reflection band (acquire/retro_band.h) take w kd + (1 - w) prior where the
  /// kd-tree has support (confidence w), the prior where not (chosen by prior_reach.h); empty: the blend as
  /// elsewhere. The cap wins where both hold. The residuals form ignores it.
  std::optional<double> retro_weight;
  /// given (with retro_weight; kMerlThetaH values, each in [0, 1]): the band's weight of the cells of each theta_h row
  /// instead of retro_weight (chosen per group of rows by prior_reach.h)
  std::vector<double> retro_weight_by_theta_h;
  /// true (with retro_weight): the band's kd-tree estimate is replaced, where it can be, by the material's trend
  /// continued down from the rows just above the band (continue_retro, acquire/retro_band.h)
  bool retro_continued = false;
  /// given (with prior_in_cap): cells of the unseen cap take w kd + (1 - w) prior where the kd-tree has support
  /// (confidence w), the prior where not (chosen by acquire/cap_weight.h); empty: the prior alone there.
  std::optional<double> cap_weight;
  /// true: where retro_weight or cap_weight sets the weight w (strictly between 0 and 1), kd and prior are mixed in
  /// the choice's error domain ln(v cos theta_i cos theta_o + blend_epsilon), a weighted geometric mean
  /// (mix_estimates below), as the choice judged them; false: linearly
  bool log_blend = true;
  /// eps of the log blend, 1/sr (the choice's, judge_epsilon; positive and finite); empty: the prior's epsilon
  std::optional<double> blend_epsilon;
  /// true: in the unseen cap, where no sample constrains it, the fit is bounded by the prior's ceiling
  /// (bound_by_ceiling); false, or a prior without a ceiling: not bounded. The residuals form ignores it.
  bool ceiling = true;
  /// given (the default): the fit is bounded by energy conservation per incident direction (bound_energy,
  /// acquire/energy_bound.h) after the ceiling, in both forms; empty: not
  std::optional<EnergyBoundOptions> energy_bound = EnergyBoundOptions{};
};

/// What one reconstruction with a prior did.
struct PriorResampleStats {
  brdf::GridStats local;                 ///< the kd-tree pass
  std::size_t observed_cells = 0;        ///< valid cells holding at least one sample (the prior's observations)
  std::size_t filled_cells = 0;          ///< valid cells with data in the result (all of them)
  std::size_t bounded_cells = 0;         ///< cap cells whose fit the prior's ceiling scaled down (bound_by_ceiling)
  std::size_t energy_bounded_cells = 0;  ///< cells whose fit the energy bound scaled down (bound_energy)
  int unseen_retro_rows = 0;             ///< theta_d rows below the lowest observed cell's (unseen_retro_rows)
  UnseenCap unseen_cap{};                ///< the cap round the peak that no observed cell reaches (unseen_cap)
  double fit_seconds = 0;
};

/// Every valid cell of grid (bands x kMerlCells) from src: confidence c per cell (written into
/// confidence, kMerlCells values, -1 below the horizon), the result as o.residuals says. UsageError on
/// sizes or bands that differ from the prior's; InputError when no sample falls in a valid cell.
/// The prior's components come from `components` block by block (fit_prior).
PriorResampleStats resample_with_prior(const brdf::SampleSource& src, const BrdfPrior& prior,
                                       const ComponentSource& components, const PriorResampleOptions& o,
                                       std::span<float> grid, std::span<float> confidence);
/// resample_with_prior with the components of prior (in memory).
PriorResampleStats resample_with_prior(const brdf::SampleSource& src, const BrdfPrior& prior,
                                       const PriorResampleOptions& o, std::span<float> grid,
                                       std::span<float> confidence);

/// How the kd-tree estimate kd and the fit are mixed with the kd-tree's weight c at a cell of cos theta_i cos theta_o
/// cc: linearly, c kd + (1 - c) fit, or (log) in the judge's domain, (exp(c ln(kd cc + eps) + (1 - c) ln(fit cc +
/// eps)) - eps) / cc, so a mix stays between the two in ratio. kd is ignored when c is 0.
double mix_estimates(double kd, double fit, double c, double cc, double eps, bool log);

/// Scales the spectrum in grid (bands x kMerlCells) of every valid cell with unseen[cell] != 0 (kMerlCells flags)
/// down, where needed, so that no band exceeds prior.ceiling / (cos theta_i cos theta_o) at the cell centre: the
/// largest value any training material has there; returns the cells scaled. Nothing for a prior without a ceiling.
/// UsageError on sizes.
std::size_t bound_by_ceiling(const BrdfPrior& prior, std::span<const std::uint8_t> unseen, std::span<float> grid);

/// The samples of src averaged per valid cell (values), their counts as weights and as spread their scatter (the
/// unbiased variance per band, 0 for one sample) or, when src carries variances and use_variance, the mean of the
/// samples' own variances (spread_is_noise): the observations of prior.h. Progress shown, Interrupted between blocks.
PriorObservations cell_means(const brdf::SampleSource& src, bool use_variance = true);
/// cell_means of the samples of each part: observations q average the samples s with part[s] == q (samples with a
/// label of parts or more are left out; part empty: every sample is in part 0). UsageError for parts 0 or a part
/// list that is neither empty nor one label per sample.
std::vector<PriorObservations> cell_means(const brdf::SampleSource& src, bool use_variance,
                                          std::span<const std::uint8_t> part, std::size_t parts);
/// Per sample (angles n x 4, radians) its valid cell's position in valid_cells(), or -1 (a direction below the
/// horizon or not finite) into out (n values), and with theta_d_rows (n values) its own theta_d row, whether its cell
/// lies above the horizon or not (kMerlThetaD for angles not finite); on all threads. UsageError on sizes.
void valid_slots(std::span<const double> angles, std::span<std::int32_t> out,
                 std::span<std::uint8_t> theta_d_rows = {});

}  // namespace specula::acquire
