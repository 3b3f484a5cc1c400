#pragma once
// A learned BRDF prior (Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for Reflectance
// Acquisition"), spectral: every training grid's spectra are reduced to C channels of a spectral basis (hat
// functions at C knot wavelengths: a spectrum is the piecewise-linear curve through its channel values), each
// channel's cos-weighted values mapped log-relatively to a per-cell reference (the median over the training
// observations), ln((rho cos_i cos_o + eps) / (ref cos_i cos_o + eps)), and PCA over the materials x channels
// observations gives a mean and components over the valid MERL cells. A capture is fitted per channel by
// Tikhonov-regularised weighted least squares on the components (docs/prior.md).
//
// Memory: building holds 4 bytes x valid cells (1.1 M) x materials x channels; the prior holds 4 bytes x cells
// x (components + 2).
#include <Eigen/Core>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// How a prior is learned.
struct PriorOptions {
  std::size_t channels = 8;    ///< knots of the spectral basis, spread evenly over the grids' wavelengths (>= 2)
  std::size_t components = 0;  ///< principal components kept; 0: all (observations - 1)
  double epsilon = 1e-3;       ///< eps of the log-relative mapping (1/sr, as Nielsen et al.)
};

/// A learned prior: PCA of log-relative mapped channels over the valid MERL cells (brdf::merl_cell_valid, in
/// cell order).
struct BrdfPrior {
  WavelengthGrid wavelengths;  ///< the training grids' bands
  std::vector<double> knots;   ///< channel knot wavelengths (nm), ascending, first and last at the ends
  double epsilon = 1e-3;
  std::vector<float> reference;       ///< per valid cell: the median cos-weighted channel value (1/sr)
  std::vector<float> mean;            ///< per valid cell: mean mapped value
  std::vector<float> components;      ///< k x valid cells, row-major, orthonormal rows
  std::vector<double> variances;      ///< k: variance of the observations along each component
  std::vector<std::string> training;  ///< the training grids, one name per material

  std::size_t cells() const { return mean.size(); }
  std::size_t k() const { return variances.size(); }
  std::size_t channels() const { return knots.size(); }
};

/// Linear indices of the valid MERL cells (both directions above the horizon), ascending: a prior's cell order.
const std::vector<std::uint32_t>& valid_cells();
/// cos(theta_i) cos(theta_o) at the centre of each valid cell, in valid_cells() order.
const std::vector<float>& valid_cell_cosines();

/// The B x C hat functions of knots at wavelengths: column j is 1 at knot j and falls linearly to 0 at its
/// neighbours (constant beyond the end knots).
Eigen::MatrixXd hat_basis(const WavelengthGrid& wavelengths, std::span<const double> knots);

/// Learns a prior from `count` grids that load(i) returns (one at a time; names[i] names grid i): all on the same
/// wavelengths, each with data at every valid cell. InputError naming the grid otherwise; UsageError for bad
/// options or fewer than 2 grids.
BrdfPrior build_prior(std::size_t count, const std::function<store::Grid(std::size_t)>& load,
                      std::span<const std::string> names, const PriorOptions& options);

/// Scattered observations of a BRDF on the prior's cells: per observed cell its index into valid_cells(), the
/// BRDF spectrum there (bands values, 1/sr) and a weight (inverse noise variance, e.g. the samples averaged).
struct PriorObservations {
  std::vector<std::uint32_t> cell;
  std::vector<float> values;  ///< cells x bands
  std::vector<float> weight;
};

/// How a prior is fitted.
struct PriorFitOptions {
  double lambda = 1e-3;  ///< Tikhonov weight: lambda * sum_i a_i^2 / variance_i is added to the weighted residual
};

/// Fits the prior to obs per channel and writes the reconstruction at every valid cell into grid (bands x
/// kMerlCells, band slowest; other cells untouched). UsageError on sizes, InputError for no observation.
void fit_prior(const BrdfPrior& prior, const PriorObservations& obs, const PriorFitOptions& options,
               std::span<float> grid);

/// Writes `prior` as object `name` of kind "priors" (docs/store-format.md).
void write_prior(store::StoreWriter& out, const std::string& name, const BrdfPrior& prior);
/// Reads prior `name`; InputError naming the store and the prior when absent or malformed.
BrdfPrior read_prior(const store::Store& in, const std::string& name);
/// Names of the priors in a store.
std::vector<std::string> prior_names(const store::Store& in);

}  // namespace specula::acquire
