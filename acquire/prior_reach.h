#pragma once
// The kd-tree's reach r in the prior's blend chosen from the scan itself (`resample --prior --confidence-reach
// auto`, docs/prior.md): a fixed-seed share of the observed cells is held out, the prior fitted and the kd-tree
// built without their samples, and at each held-out cell the blend c(g, r) kd + (1 - c) prior of every candidate r
// (g from the cell centre to the nearest kept sample) is compared with the mean of the cell's held-out samples in
// the log domain of the fit. Half the held-out cells lose all their samples (as the unobserved cells next to data)
// and half only every other one (as the observed cells, whose own samples are near); the two errors are weighed by
// how many cells of the scan are of each kind, and the r of least error is kept.
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
  double held_out = 0.1;   ///< share of the observed cells held out, in (0, 1)
  std::uint64_t seed = 0;  ///< seed of the choice of held-out cells
};

/// What a sample is in the validation.
enum class ReachRole : std::uint8_t {
  kept = 0,   ///< fitted and in the kd-tree
  split = 1,  ///< held out of a cell that keeps its other samples (every other one, in sample order)
  whole = 2,  ///< held out with all its cell's samples
};

/// Which samples the validation holds out.
struct ReachHoldout {
  std::vector<ReachRole> role;     ///< per sample
  std::size_t observed_cells = 0;  ///< valid cells holding a sample
  std::size_t split_cells = 0, whole_cells = 0;
};

/// The held-out cells: round(held_out x observed cells) of them by selection sampling seeded by o.seed over the
/// observed valid cells in cell order; of these, the 1st, 3rd, ... lose all their samples and the 2nd, 4th, ... every
/// other sample (the 2nd, 4th, ... in sample order; a cell of one sample loses it whole). UsageError for bad options,
/// InputError when fewer than 2 valid cells hold a sample.
ReachHoldout reach_holdout(const SampleSource& src, const ReachOptions& o);

/// One candidate reach: the mean log-domain error over the held-out cells of each kind, and their weighted sum.
struct ReachRow {
  double reach = 0;
  double error = 0;             ///< (split_weight x split + whole_weight x whole) / (split_weight + whole_weight)
  double split = 0, whole = 0;  ///< means over the split and whole held-out cells (0 without any)
};

/// What the choice found.
struct ReachChoice {
  double reach = 0;      ///< the ladder's r of least error (the smaller on a tie)
  ReachHoldout holdout;  ///< without its roles
  /// the scan's observed cells, and its unobserved valid cells whose nearest kept sample is no farther than the
  /// farthest held-out whole cell's (each kind's cells of the scan, counted; 0 for a kind without held-out cells)
  double split_weight = 0, whole_weight = 0;
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

/// The choice and every row, as `resample --json` reports it under "confidence_reach_auto".
nlohmann::ordered_json reach_choice_json(const ReachChoice& c, const ReachOptions& r);

/// "confidence_reach=R reach_auto=holdout held_out=S seed=N": how the grid's provenance names a chosen reach.
std::string reach_provenance(const ReachChoice& c, const ReachOptions& r);

}  // namespace specula::acquire
