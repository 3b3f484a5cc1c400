#pragma once
// Designing K broadband filters for a spectral basis (the reference's chapter 8): from an NMF basis (its
// components, smoothed, as transmission curves) or optimised for the expected reconstruction error of a set of
// spectra under camera noise (docs/filters.md states the criterion and the optimiser).
#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "specula/acquire/capture.h"
#include "specula/acquire/filters.h"
#include "specula/store/basis.h"
#include "specula/store/store.h"

namespace specula::acquire {

enum class FilterMethod { nmf, optimal };

/// "nmf" or "optimal"; UsageError otherwise.
FilterMethod parse_filter_method(const std::string& name);

/// How K readings become a spectrum: a ridge solve in the basis's first columns (filter_recovery) or the Wiener
/// solve with the spectra's second moment as prior (filter_wiener_recovery).
enum class FilterSolve { ridge, wiener };

/// "ridge" or "wiener"; UsageError otherwise.
FilterSolve parse_filter_solve(const std::string& name);

struct FilterDesignOptions {
  FilterMethod method = FilterMethod::optimal;
  FilterSolve solve = FilterSolve::wiener;
  int k = 6;                        ///< filters
  double noise = 0.002;             ///< camera noise: standard deviation relative to a white reading (below)
  bool per_filter_exposure = true;  ///< noise relative to each filter's white reading, else an open filter's
  /// per filter exposure: the light (a fraction of an open filter's white reading) below which a filter's exposure
  /// reaches the camera's longest and its noise stops falling with its signal (docs/filters.md)
  double min_throughput = 0.01;
  /// optimal: weight of the expected colour error (colour_rows) against the spectral one per band in the criterion
  /// (100: chosen on held-out Munsell chips, docs/filters.md)
  double colour_weight = 100;
  double ridge = 1e-3;         ///< the solve's regularisation (filter_recovery)
  double peak = 0.9;           ///< the curves' largest transmission
  double light_kelvin = 3200;  ///< the light (a blackbody) the design assumes, with the simulated camera's response
  double step_nm = 5;          ///< the curves' tabulation step
  double smooth_nm = 10;       ///< nmf: Gaussian smoothing (standard deviation) of the components
};

/// UsageError stating the rule for a bad option.
void check_filter_design(const FilterDesignOptions& o);

/// The basis columns a reconstruction with k filters uses (B x r): the first k NMF components, or the PCA mean and
/// the first k - 1 components (r never above the basis's own components, plus its mean).
Eigen::MatrixXd reconstruction_basis(const store::Basis& basis, int k);

/// reconstruction_basis for a filter capture (k: its filters); InputError naming `label` unless the basis is on the
/// capture's bands, and for a capture without filters.
Eigen::MatrixXd capture_basis(const store::Basis& basis, const Capture& capture, const std::string& label);

/// The basis's second moment (B x B), the Wiener solve's prior, for a filter capture: the checks of capture_basis,
/// and InputError naming `label` for a basis that stores none.
Eigen::MatrixXd capture_prior(const store::Basis& basis, const Capture& capture, const std::string& label);

/// CIE 1931 XYZ of a reflectance on `bands` under D65 and under A (6 x B, band sums, each illuminant scaled so a
/// white's Y is 1, rows divided by sqrt(6) so that |rows * x|^2 is the mean over the six of the squared error), the
/// colour the lighting suite renders (codec/suite.h): the optimal design's colour term.
Eigen::MatrixXd colour_rows(std::span<const double> bands);

/// Expected reconstruction error of spectra (rows, on `bands`) read through filters `f` (sensitivity s: light times
/// camera response), with noise of standard deviation `noise` added to each reading, relative to the filter's own
/// white reading (per_filter_exposure: each filter exposed to fill the sensor, but no filter's reading taken as
/// below min_throughput of an open filter's: its exposure is capped) or else to an open filter's (every
/// filter exposed alike), solved in `basis` with `ridge` or, when `prior`
/// (a B x B second moment) is not empty, by the Wiener solve: per spectrum
/// sqrt((|x - R A x|^2 + |R diag(sigma)|_F^2) / B), sigma the readings' noise.
struct FilterError {
  std::size_t spectra = 0;
  double rms_mean = 0, rms_median = 0, rms_max = 0;
  double noise_rms = 0;  ///< the noise term alone: |R diag(sigma)|_F / sqrt(B)
};
FilterError expected_filter_error(const FilterSet& f, std::span<const double> bands, const Tabulated& s,
                                  const Eigen::MatrixXd& basis, const Eigen::MatrixXd& spectra, double noise,
                                  double ridge, const Eigen::MatrixXd& prior = {}, bool per_filter_exposure = false,
                                  double min_throughput = 0);

/// Each filter's white reading (light times `s` over the bands) as a fraction of an open filter's (transmission 1).
std::vector<double> filter_throughput(const FilterSet& f, std::span<const double> bands, const Tabulated& s);

/// Designs o.k filters on the basis's wavelengths: nmf smooths and scales the NMF basis's first k components;
/// optimal minimises the mean expected squared error of `training` (spectra as rows; solved as o.solve says, the
/// Wiener solve with the training spectra's second moment) over each filter's centre, width and flatness (a
/// super-Gaussian of peak o.peak) by Nelder-Mead from evenly spaced filters.
FilterSet design_filters(const store::Basis& basis, const Eigen::MatrixXd& training, const FilterDesignOptions& o);

/// The design of design_filters on a store's basis and collections, with its expected error on the training
/// spectra and on held-out ones (collection `test`, or when empty every fifth training spectrum, left out of the
/// optimisation).
struct FilterDesign {
  FilterSet filters;
  std::vector<double> bands;
  FilterError training, held_out;
  std::string training_name, held_out_name;
};
/// `train` empty: the collection the basis was learned from ("collection NAME"). InputError naming the store for
/// a missing basis or collection, or a collection on other wavelengths than the basis.
FilterDesign design_filters(const store::Store& s, const std::string& basis, const std::string& train,
                            const std::string& test, const FilterDesignOptions& o);

/// The light times the simulated camera's response (simulate.h) the design assumes, on its tabulation.
Tabulated design_sensitivity(double light_kelvin);

}  // namespace specula::acquire
