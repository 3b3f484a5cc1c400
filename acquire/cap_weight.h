#pragma once
// The kd-tree's weight in the unseen cap round the specular peak (acquire/peak_cap.h) chosen from the scan
// (`resample --prior`, docs/prior.md). In the cap the prior's fit continues the peak as its training materials'
// peaks continue, the kd-tree's estimate continues the material's own nearest samples nearly flat: a glossy material
// wants the first, a flat one (a fabric) the second. Rehearsed one cap higher: every sample of the theta_h rows
// [C, min(2 C, 90)) of each theta_d row (C its cap's depth, 0 < C < 90) is held out, the prior fitted and the kd-tree
// built without them, and at those rows' observed cells each weight w of the ladder is judged by the error of
// w kd + (1 - w) fit against the cell's samples, as the retro band's weight is (acquire/scan_holdout.h).
#include <nlohmann/json_fwd.hpp>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/acquire/prior_resample.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

struct CapWeightOptions {
  std::vector<double> ladder = {0, 0.25, 0.5, 0.75, 1};  ///< the kd-tree's weights tried, ascending in [0, 1]
};

/// One weight and its mean error over the rehearsal cells.
struct CapWeightRow {
  double weight = 0;
  double error = 0;
};

struct CapWeightChoice {
  double weight = 0;               ///< the ladder's weight of least error (the smaller on a tie)
  std::vector<CapWeightRow> rows;  ///< one per ladder entry; empty when nothing could be rehearsed (weight 0)
  std::size_t held_samples = 0;    ///< samples held out (the rehearsal rows')
  std::size_t held_cells = 0;      ///< their observed cells
  std::vector<int> cap_rows;       ///< per theta_d row the cap's depth C (acquire/peak_cap.h)
  double epsilon = 0;              ///< eps of the error (judge_epsilon of the kept samples)
  double seconds = 0;
};

/// Chooses PriorResampleOptions::cap_weight for resample_with_prior(src, prior, components, o) as the header says:
/// the fit (o.fit, bounded by the ceiling in the rehearsal rows when o.ceiling) to the kept samples' cell means and
/// the kd-tree (o.local) over the kept samples. Weight 0 (the prior alone) when no theta_d row has a cap with rows
/// above it to rehearse in. The same for any thread count. UsageError for a bad ladder or o.residuals; errors of
/// fit_prior.
CapWeightChoice choose_cap_weight(const brdf::SampleSource& src, const BrdfPrior& prior,
                                  const ComponentSource& components, const PriorResampleOptions& o,
                                  const CapWeightOptions& c);

/// The choice, as `resample --json` reports it under "cap_weight_auto".
nlohmann::ordered_json cap_weight_json(const CapWeightChoice& c);

}  // namespace specula::acquire
