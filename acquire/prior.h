#pragma once
// A learned BRDF prior (Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for Reflectance
// Acquisition"), spectral: every training grid's spectra are reduced to C channels of a spectral basis (hat
// functions at C knot wavelengths: a spectrum is the piecewise-linear curve through its channel values), each
// channel's cos-weighted values mapped log-relatively to a per-cell reference (the median over the training
// observations), ln((rho cos_i cos_o + eps) / (ref cos_i cos_o + eps)), and PCA over the materials x channels
// observations gives a mean and components over the valid MERL cells. A capture is fitted per channel by
// Tikhonov-regularised weighted least squares on the components (docs/prior.md).
//
// Memory: building streams blocks of cells from the grids (PriorOptions::block_bytes); fitting streams blocks of the
// components from wherever they are (a ComponentSource: the store, or a prior in memory; PriorFitOptions::block_bytes).
#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// How a prior is learned.
struct PriorOptions {
  std::size_t channels = 8;    ///< knots of the spectral basis, spread evenly over the grids' wavelengths (>= 2)
  std::size_t components = 0;  ///< principal components kept; 0: all (observations - 1)
  double epsilon = 1e-3;       ///< eps of the log-relative mapping (1/sr, as Nielsen et al.)
  std::size_t block_bytes = std::size_t(256) << 20;  ///< memory for a block's cells x observations (float32)
};

/// A learned prior: PCA of log-relative mapped channels over the valid MERL cells (brdf::merl_cell_valid, in
/// cell order).
struct BrdfPrior {
  WavelengthGrid wavelengths;  ///< the training grids' bands
  std::vector<double> knots;   ///< channel knot wavelengths (nm), ascending, first and last at the ends
  double epsilon = 1e-3;
  std::vector<float> reference;  ///< per valid cell: the median cos-weighted channel value (1/sr)
  std::vector<float> mean;       ///< per valid cell: mean mapped value
  /// per valid cell: the largest cos-weighted channel value of any training material (1/sr); empty for a prior
  /// written before it was kept (store version 1)
  std::vector<float> ceiling;
  std::vector<float> components;      ///< k x valid cells, row-major, orthonormal rows
  std::vector<double> variances;      ///< k: variance of the observations along each component
  std::vector<std::string> training;  ///< the training grids, one name per material
  /// per width B = 1, 2, ... of the unseen retro band (theta_d rows) the exponent p its continuation fits ln v against
  /// theta_d^p with (acquire/retro_trend.h), learned from the training grids; empty for a prior written before it was
  /// learned (store version <= 2), which continues with p = 2
  std::vector<double> retro_exponents;
  /// per width of the unseen retro band the ridge map from its shoulder's profile to its own (acquire/retro_rise.h:
  /// retro_rise_size() values), learned from the training grids; empty for a prior written before it was learned
  /// (store version <= 3)
  std::vector<double> retro_rise;

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
/// The C x B least-squares projection of a spectrum onto the hat functions hats (B x C): (H'H)^-1 H'.
Eigen::MatrixXd hat_projection(const Eigen::MatrixXd& hats);
/// Cells of whole blocks of a prior's component storage (store::kPriorBlockCells cells each), as many as bytes holds
/// at cell_bytes a cell, at least one block.
std::size_t prior_block_cells(std::size_t bytes, std::size_t cell_bytes);
/// The prior's mapping of a cos-weighted value x against the cell's reference ref: ln((x + eps) / (ref + eps)).
inline float prior_mapped(float x, float ref, double eps) {
  return float(std::log((double(x) + eps) / (double(ref) + eps)));
}

/// One training grid, read block by block in whole theta_h rows.
struct TrainingGrid {
  std::string name;
  WavelengthGrid wavelengths;
  double scale = 1;
  /// theta_h rows [h0, h0 + rows) into out: bands x rows x 90 x 180 unscaled values.
  std::function<void(std::size_t h0, std::size_t rows, std::span<float> out)> read_rows;
};
/// Grid `name` of store s, read by rows from the store (only the chunks a block needs); InputError when absent.
TrainingGrid store_training_grid(const store::Store& s, const std::string& name, const std::string& label);
/// A grid in memory, shared (not copied).
TrainingGrid memory_training_grid(std::shared_ptr<const store::Grid> grid, const std::string& name);
/// A grid load() returns, loaded once for its bands and again for each block it is read in (nothing held between).
TrainingGrid reloaded_training_grid(const std::string& name, const std::function<store::Grid()>& load);

/// What names training grids: a spec (as `prior build GRID` takes it), an open store (all its grids), or a grid made.
using TrainingSource = std::variant<std::string, store::Store, TrainingGrid>;
/// The grids sources name, in order, as `specula prior build GRID...` reads them: "STORE.h5:GRID" streams that grid by
/// rows (each store opened once), a whole "STORE.h5" (no :GRID) or an open store stands for all its grids (named
/// "STORE.h5:GRID"), a TrainingGrid is kept, any other spec is other(spec); a grid whose name or whole spec is in
/// exclude is left out. UsageError "COMMAND: give at least 2 training grids (after EXCLUDE_NAME)" before any grid is
/// read; InputError naming the store for a missing store or grid.
std::vector<TrainingGrid> training_grids(std::span<const TrainingSource> sources, std::span<const std::string> exclude,
                                         const std::function<TrainingGrid(const std::string&)>& other,
                                         std::string_view command, std::string_view exclude_name);

/// Fills out with the k x count components of cells [first, first + count) (row-major). A prior being built makes
/// them for consecutive blocks of store::kPriorBlockCells cells in cell order; a stored or in-memory prior reads any
/// range.
using ComponentSource = std::function<void(std::size_t first, std::size_t count, std::span<float> out)>;

/// Learns a prior from grids, all on the same wavelengths, each with data at every valid cell, in two passes over
/// blocks of cells (each reading the block's rows of every grid): the per-cell reference and mean, the Gram matrix of
/// the observations, the retro band's exponents (RetroExponentTally over the grids' channels) and rise maps
/// (RetroRiseTally over their bands); then, as sink asks
/// for them, the components. sink gets the prior without its components and their source (valid during the call).
/// Memory: options.block_bytes plus one grid's rows of a block. The result does not depend on the thread count or
/// block_bytes. InputError naming the grid for other bands or holes; UsageError for bad options or fewer than 2 grids.
/// Returns the prior without its components.
BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& options,
                      const std::function<void(const BrdfPrior&, ComponentSource)>& sink);
/// build_prior into memory (the whole prior, components included).
BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& options);
/// build_prior of `count` grids that load(i) returns, held in memory while building (names[i] names grid i).
BrdfPrior build_prior(std::size_t count, const std::function<store::Grid(std::size_t)>& load,
                      std::span<const std::string> names, const PriorOptions& options);
/// build_prior streamed into prior `name` of the transaction out (components written block by block), its provenance
/// naming command_line (empty: the transaction's); returns the prior's tables without its components.
BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& options, store::StoreWriter& out,
                      const std::string& name, const std::string& command_line = {});

/// Scattered observations of a BRDF on the prior's cells: per observed cell its index into valid_cells(), the
/// BRDF spectrum there (bands values, 1/sr), the samples it averages and, when known, their noise.
struct PriorObservations {
  std::vector<std::uint32_t> cell;
  std::vector<float> values;  ///< cells x bands
  std::vector<float> weight;  ///< samples averaged (n), or any weight proportional to the mean's inverse variance
  /// cells x bands, or empty (unknown): the variance of one sample about the cell's mean (1/sr^2), from the samples'
  /// scatter (cell_means) or a noise model; with it the fit weighs a cell by n / its noise (PriorFitOptions).
  std::vector<float> spread;
  /// true: spread is the mean of the samples' own noise variances (acquisition's noise model, known exactly, so not
  /// shrunk toward the median cell's); false: the samples' scatter.
  bool spread_is_noise = false;
};

/// How a cell's observation is weighted in the fit (docs/prior.md).
enum class PriorWeights {
  noise,    ///< n / sigma^2: sigma^2 the samples' own variance when they carry one, else their scatter (shrunk)
  count,    ///< n, the samples averaged (as if every sample had the same noise)
  scatter,  ///< as noise, from the samples' scatter even when they carry a variance
};

/// Parses "noise", "count" or "scatter"; UsageError naming the choices otherwise.
PriorWeights parse_prior_weights(std::string_view name);
/// "noise", "count" or "scatter".
std::string_view prior_weights_name(PriorWeights w);

/// How a prior is fitted.
struct PriorFitOptions {
  double lambda = 1e-3;  ///< Tikhonov weight: lambda * sum_i a_i^2 / variance_i is added to the weighted residual
  PriorWeights weights = PriorWeights::noise;  ///< noise needs PriorObservations::spread; count without it
  double noise_shrinkage = 2;  ///< nu0: pseudo-samples at the median noise a cell's own scatter is pooled with
  double noise_floor = 0.01;   ///< a cell's noise variance is at least this fraction of the median cell's
  /// memory for one block of k x cells components (float32), rounded to whole blocks of store::kPriorBlockCells
  std::size_t block_bytes = std::size_t(256) << 20;
};

/// Per observation its weight in the fit: n (count, or no spread) or n sigma0^2 / sigma^2 (noise), sigma^2 the
/// cell's per-sample noise variance in the mapped domain, (nu0 sigma0^2 + (n - 1) s^2) / (nu0 + n - 1) floored at
/// noise_floor sigma0^2, s^2 its scatter, sigma0^2 the median s^2 of the cells with n >= 2; with spread_is_noise,
/// sigma^2 = s^2 (the samples' own variance, every cell) floored likewise. UsageError on sizes.
std::vector<double> observation_weights(const BrdfPrior& prior, const PriorObservations& obs,
                                        const PriorFitOptions& options);

/// Fits the prior (its tables; components from `components`) to obs per channel and writes the reconstruction at
/// every valid cell, or at the valid cells `at` alone (positions in valid_cells(), ascending), into grid (bands x
/// kMerlCells, band slowest; other cells untouched), in two passes over blocks of options.block_bytes: the normal
/// equations of each block's observed cells, then the reconstruction of each block's cells; a block with nothing to
/// add or write is not read. The result does not depend on the thread count, block_bytes or `at`. UsageError on
/// sizes, `at` out of order or a weight not finite and >= 0, InputError for no observation.
void fit_prior(const BrdfPrior& prior, const ComponentSource& components, const PriorObservations& obs,
               const PriorFitOptions& options, std::span<float> grid, std::span<const std::uint32_t> at = {});
/// fit_prior with the components of prior (in memory).
void fit_prior(const BrdfPrior& prior, const PriorObservations& obs, const PriorFitOptions& options,
               std::span<float> grid);
/// The components of prior, in memory (referenced, not copied): any range of cells.
ComponentSource memory_components(const BrdfPrior& prior);

/// Writes `prior` as object `name` of kind "priors" (docs/store-format.md).
void write_prior(store::StoreWriter& out, const std::string& name, const BrdfPrior& prior);
/// Reads prior `name`; InputError naming the store and the prior when absent or malformed.
BrdfPrior read_prior(const store::Store& in, const std::string& name);
/// Reads prior `name` without its components (their shape checked); InputError as read_prior.
BrdfPrior read_prior_tables(const store::Store& in, const std::string& name);
/// The components of prior `name` of store in, read from it range by range (the store shared, not copied).
ComponentSource store_components(const store::Store& in, const std::string& name);
/// Names of the priors in a store.
std::vector<std::string> prior_names(const store::Store& in);

}  // namespace specula::acquire
