#pragma once
// The kd-tree's reach r in the prior's blend chosen from the scan itself (`resample --prior --confidence-reach
// auto`, docs/prior.md): in a fixed-seed share of the observed cells of two or more samples every other sample is held
// out, the prior fitted and the kd-tree built without them, and at each such cell the blend c(g, r) kd + (1 - c) prior
// of every candidate r (g from the cell centre to the nearest kept sample) is compared with the mean of the cell's
// held-out samples in the log domain of the fit; the r of least mean error is kept.
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <span>
#include <string>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/resample.h"

namespace specula::acquire {

struct ReachOptions {
  std::vector<double> ladder = {0.001, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5, 1};  ///< ascending, in (0, 1]
  double held_out = 0.1;   ///< share of the observed cells of two or more samples held out, in (0, 1)
  std::uint64_t seed = 0;  ///< seed of the choice of held-out cells
};

/// Which samples the validation holds out.
struct ReachHoldout {
  std::vector<std::uint8_t> held;  ///< per sample: 1 held out, 0 kept (fitted and in the kd-tree)
  std::size_t observed_cells = 0;  ///< valid cells holding a sample
  std::size_t held_cells = 0;      ///< cells that lose samples
};

/// The held-out cells: round(held_out x the observed valid cells of two or more samples) of those (at least one), by
/// selection sampling seeded by o.seed over them in cell order; each loses its 2nd, 4th, ... sample in sample order.
/// UsageError for bad options, InputError when no valid cell holds two samples.
ReachHoldout reach_holdout(const SampleSource& src, const ReachOptions& o);

/// One candidate reach and its mean log-domain error over the held-out cells.
struct ReachRow {
  double reach = 0;
  double error = 0;
};

/// What the choice found.
struct ReachChoice {
  double reach = 0;            ///< the ladder's r of least error (the smaller on a tie)
  ReachHoldout holdout;        ///< without its per-sample flags
  std::vector<ReachRow> rows;  ///< one per ladder entry
  double seconds = 0;
};

/// Chooses o.confidence_reach for resample_with_prior(src, prior, o) on the holdout of reach_holdout: the prior fitted
/// (o.fit) to the kept samples' cell means, the kd-tree (o.local) built over the kept samples, and at every held-out
/// cell, for every ladder r, the mean over bands of (ln((blend cos_i cos_o + eps) / (target cos_i cos_o + eps)))^2,
/// eps the prior's, target the held-out samples' mean; on all threads, the same for any thread count. UsageError for
/// bad options or o.residuals (the residuals form is not a blend); errors of reach_holdout and fit_prior.
ReachChoice choose_confidence_reach(const SampleSource& src, const BrdfPrior& prior, const PriorResampleOptions& o,
                                    const ReachOptions& r);
/// choose_confidence_reach with the prior's components from `components` block by block (fit_prior).
ReachChoice choose_confidence_reach(const SampleSource& src, const BrdfPrior& prior, const ComponentSource& components,
                                    const PriorResampleOptions& o, const ReachOptions& r);

/// The choice and every row, as `resample --json` reports it under "confidence_reach_auto".
nlohmann::ordered_json reach_choice_json(const ReachChoice& c, const ReachOptions& r);

/// "confidence_reach=R reach_auto=holdout held_out=S seed=N": how the grid's provenance names a chosen reach.
std::string reach_provenance(const ReachChoice& c, const ReachOptions& r);

}  // namespace specula::acquire
