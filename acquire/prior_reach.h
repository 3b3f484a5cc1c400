#pragma once
// The kd-tree's reach r in the prior's blend chosen from the scan itself (`resample --prior --confidence-reach
// auto`, docs/prior.md): in a fixed-seed share of the observed cells of two or more samples every other sample is held
// out, the prior fitted and the kd-tree built without them, and at each such cell the blend c(g, r) kd + (1 - c) prior
// of every candidate r (g from the cell centre to the nearest kept sample) is compared with the mean of the cell's
// held-out samples in the log domain of the fit, its eps scaled down to a material darker than the prior's reference;
// the r of least mean error is kept.
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/retro_residual.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

struct ReachOptions {
  std::vector<double> ladder = {0.001, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5, 1};  ///< ascending, in (0, 1]
  double held_out = 0.1;   ///< share of the observed cells of two or more samples held out, in (0, 1)
  std::uint64_t seed = 0;  ///< seed of the choice of held-out cells
  /// the kd-tree's weights tried in the unseen retro-reflection band (acquire/retro_band.h), ascending in [0, 1];
  /// empty: the band is not chosen for (and not held out)
  std::vector<double> retro_ladder = {0, 0.25, 0.5, 0.75, 1};
  /// true: the ladder is tried a second time with the kd-tree's estimate in the band replaced by the material's trend
  /// continued down in theta_d (continue_retro of acquire/retro_band.h), and the better of the two kept
  bool retro_continued = true;
  /// true: each theta_h group below chooses the band's weight from its own held band cells (the overall weight where
  /// it has fewer than min_group_cells of them); false: one weight for the whole band
  bool retro_by_group = true;
  /// theta_h row boundaries of the groups that each choose their reach (ascending from 0 to kMerlThetaH); {0, 90}:
  /// one reach for all
  std::vector<int> theta_h_groups = {0, 10, 20, 30, 45, 90};
  /// a group with fewer held-out cells (or held band cells) takes the reach (band weight) chosen over all of them
  std::size_t min_group_cells = 200;
  /// the kd-tree's neighbour counts tried with the reach, ascending, each >= 1: the k whose least error over the
  /// ladder is least is kept (the smaller on a tie); empty: the options' k alone
  std::vector<std::size_t> k_ladder;
  /// given: whether the samples' log residuals (with these radius and passes) are carried into the band is rehearsed
  /// on the held band too (acquire/retro_residual.h); empty: not chosen for
  std::optional<LogResidualOptions> retro_residuals;
};

/// The neighbour counts `resample --prior -k holdout` tries with the reach (ReachOptions::k_ladder).
inline const std::vector<std::size_t> kReachKLadder = {8, 16, 32, 64};

/// Which samples the validation holds out.
struct ReachHoldout {
  /// per sample: 0 kept (fitted and in the kd-tree), 1 held out of a split cell, 2 held out with its theta_d row
  std::vector<std::uint8_t> held;
  std::vector<std::uint8_t> theta_d_row;  ///< per sample its own theta_d row (kMerlThetaD for angles not finite)
  std::size_t observed_cells = 0;         ///< valid cells holding a sample
  std::size_t held_cells = 0;             ///< cells that lose samples (split)
  int retro_rows = 0;                     ///< theta_d rows below the lowest observed one (the unseen band)
  int band_first = 0, band_end = 0;       ///< theta_d rows [first, end) held out whole: the band one band higher
};

/// The held-out cells: round(held_out x the observed valid cells of two or more samples outside the held band) of
/// those (at least one), by selection sampling seeded by o.seed over them in cell order; each loses its 2nd, 4th, ...
/// sample in sample order. With a retro ladder and an unseen band of R > 0 theta_d rows, every sample whose own theta_d
/// row lies in [R, min(2R, 90)) is held out too (label 2), and every sample below those rows whose cell lies below the
/// horizon: the band's extrapolation rehearsed one band higher. UsageError for bad options, InputError when no valid
/// cell holds two samples.
ReachHoldout reach_holdout(const brdf::SampleSource& src, const ReachOptions& o);

/// One candidate reach and its mean log-domain error over the held-out cells.
struct ReachRow {
  double reach = 0;
  double error = 0;
};

/// What the choice found.
/// One group of theta_h rows and its choice.
struct ReachGroup {
  int first = 0, end = 0;  ///< theta_h rows [first, end)
  std::size_t cells = 0;   ///< held-out cells in it
  double reach = 0;        ///< its r of least error, or the overall one when cells < min_group_cells
  std::vector<ReachRow> rows;
  std::size_t retro_cells = 0;  ///< held band cells in it
  /// its band weight (of the chosen ladder, plain or continued): of least error over its retro_cells, or the overall
  /// one when retro_cells < min_group_cells or the choice is not by group; empty without a band
  std::optional<double> retro_weight;
  std::vector<ReachRow> retro_rows;  ///< the chosen ladder's errors over its retro_cells
};

struct ReachChoice {
  std::size_t k = 0;               ///< the kd-tree's neighbour count the rest was chosen with (ReachOptions::k_ladder)
  std::vector<ReachRow> k_rows;    ///< per k of the k ladder (as reach) its least error over the reach ladder
  double reach = 0;                ///< the ladder's r of least error over all held-out cells (the smaller on a tie)
  std::vector<ReachGroup> groups;  ///< one per theta_h group
  /// the chosen retro ladder's weight of least error at all the held band's cells (the smaller on a tie); empty without
  /// a band. The groups may each take their own (ReachGroup::retro_weight).
  std::optional<double> retro_weight;
  std::vector<ReachRow> retro_rows;  ///< one per retro ladder entry: its weight (as reach) and error
  /// with the estimate continued in theta_d in place of the kd-tree's (empty unless retro_continued and a band)
  std::vector<ReachRow> retro_continued_rows;
  /// the band's weights are of the continued estimate: with the groups' weights its error over the held band is lower
  bool retro_continued = false;
  /// the exponent the band is continued with: the prior's for the band's width (retro_exponent of
  /// acquire/retro_trend.h)
  double retro_exponent = 2;
  /// the carry of the log residuals into the band rehearsed (ReachOptions::retro_residuals) on the blend the choices
  /// above make from the kept samples; empty when not asked for or without a held band
  std::optional<RetroResidualChoice> retro_residuals;
  ReachHoldout holdout;        ///< without its per-sample flags and rows
  std::vector<ReachRow> rows;  ///< one per ladder entry
  double epsilon = 0;          ///< eps of the error: the prior's times min(1, kept cell means' median / reference's)
  double seconds = 0;
};

/// Chooses o.confidence_reach for resample_with_prior(src, prior, o) on the holdout of reach_holdout: the prior fitted
/// (o.fit) to the kept samples' cell means, the kd-tree (o.local, or of r.k_ladder the k of least error, each k's
/// estimate made at the held-out cells alone) built over the kept samples, and at every held-out cell, for every ladder
/// r, the mean over bands of (ln((blend cos_i cos_o + eps) / (target cos_i cos_o + eps)))^2, eps the prior's times
/// min(1, the kept cell means' median cos-weighted band mean / the prior's median reference at the same cells), target
/// the held-out samples' mean; on all threads, the same for any thread count. UsageError for bad options or o.residuals
/// (the residuals form is not a blend); errors of reach_holdout and fit_prior. With r.retro_residuals and a held band,
/// the carry of the log residuals into the band is rehearsed on the blend these choices make from the kept samples
/// (choose_retro_residuals of acquire/retro_residual.h; from those below carry_rehearsal_rows, which give the same).
/// The fit and the kd-tree's estimate are made only where these read them (the held-out cells, the held band, the
/// rows above it its continuation and the carry read), each cell as over the whole grid.
ReachChoice choose_confidence_reach(const brdf::SampleSource& src, const BrdfPrior& prior,
                                    const PriorResampleOptions& o, const ReachOptions& r);
/// choose_confidence_reach with the prior's components from `components` block by block (fit_prior).
ReachChoice choose_confidence_reach(const brdf::SampleSource& src, const BrdfPrior& prior,
                                    const ComponentSource& components, const PriorResampleOptions& o,
                                    const ReachOptions& r);

/// Per theta_h row the reach of its group (PriorResampleOptions::reach_by_theta_h).
std::vector<double> reach_by_theta_h(const ReachChoice& c);
/// Per theta_h row the band weight of its group (PriorResampleOptions::retro_weight_by_theta_h); empty without a band.
std::vector<double> retro_weight_by_theta_h(const ReachChoice& c);

/// The choice and every row, as `resample --json` reports it under "confidence_reach_auto".
nlohmann::ordered_json reach_choice_json(const ReachChoice& c, const ReachOptions& r);

/// "confidence_reach=R reach_by_theta_h=0-10:R0,... reach_auto=holdout held_out=S seed=N[ retro_weight=W
/// retro_by_theta_h=0-10:W0,... retro_rows=B[ retro=continued retro_exponent=P][ retro_residuals=carried|plain]]": how
/// the grid's provenance names the chosen reaches (and band weights).
std::string reach_provenance(const ReachChoice& c, const ReachOptions& r);

}  // namespace specula::acquire
