#pragma once
// Resampling against a base BRDF (docs/resampling.md, "A base and its residuals"): the samples' residuals against
// a base (a fitted model or a fitted prior) are resampled with the kd-tree and Shepard weights of
// core/brdf_resample.h and added back to the base, scaled by a per-cell confidence c = max(0, 1 - (g / (r
// max_gap))^2) of the distance g from the cell centre to its nearest sample (config_distance, as the kd-tree's
// support test). The base carries what the local average would smear (a sharp specular lobe) and fills the cells
// far from data; the local data correct it where they are. Also: the model fit of acquire/model_fit.h as such a base.
#include <functional>
#include <memory>
#include <span>

#include "specula/acquire/model_fit.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// The base at scattered configurations: angles n x 4 (theta_i, phi_i, theta_o, phi_o) into values n x bands; NaN
/// where it has no value (the sample's residual is then taken as 0).
using BaseAtSamples = std::function<void(std::span<const double> angles, std::span<float> values)>;

/// c = max(0, 1 - (gap / (reach * max_gap))^2): 1 at a sample, 0 from reach * max_gap on.
double support_confidence(double gap, double max_gap, double reach);

/// grid (bands x kMerlCells) holds the base at every valid cell on entry; on return, at every valid cell, max(0,
/// base + c * the kd-tree estimate of the residuals src - base) with c (kMerlCells values, -1 below the horizon)
/// written into confidence. UsageError on sizes or a reach outside (0, 1].
brdf::GridStats resample_on_base(const brdf::SampleSource& src, const brdf::ResampleOptions& o, double reach,
                                 const BaseAtSamples& base, std::span<float> grid, std::span<float> confidence);

/// A base given at the MERL cells (bands x kMerlCells): a sample's base value is that of its cell (NaN in a cell
/// without a value, < 0).
BaseAtSamples base_from_grid(std::span<const float> grid, std::size_t bands);

struct ModelResampleOptions {
  brdf::ResampleOptions local;  ///< the kd-tree estimate of the residuals
  ModelFitOptions fit;
  double confidence_reach = 1;  ///< r of support_confidence (0 < r <= 1)
};

/// What one reconstruction with a model did.
struct ModelResampleStats {
  brdf::GridStats local;
  ModelFitReport fit;
  std::size_t filled_cells = 0;  ///< valid cells with data (all of them)
  double fit_seconds = 0;
};

/// The model fitted to src's cell means (its bands on `bands`) as the base of resample_on_base: every valid cell
/// of grid gets data. The fitted model into *model when given. Errors as fit_model and resample_on_base.
ModelResampleStats resample_with_model(const brdf::SampleSource& src, const WavelengthGrid& bands,
                                       const ModelResampleOptions& o, std::span<float> grid,
                                       std::span<float> confidence, std::unique_ptr<MicrofacetBrdf>* model = nullptr);

}  // namespace specula::acquire
