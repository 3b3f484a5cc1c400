#pragma once
// Broadband filters on a filter wheel in place of the LCTF (the reference's chapter 8): K transmission curves, their
// CSV file, the system model on the capture's bands, its calibration on targets of known reflectance (as §4.1.3 does
// for the LCTF) and the regularised solve in a spectral basis that turns K readings into a spectrum on the bands.
#include <Eigen/Core>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "specula/acquire/filter_set.h"
#include "specula/acquire/spectral.h"

namespace specula::acquire {

/// Parses the filter CSV (header "wavelength_nm,NAME,...", then one row per wavelength): InputError naming `source`
/// and the line for a malformed table, negative or non-finite values, values above 1 or wavelengths that do not
/// increase.
FilterSet parse_filters_csv(std::string_view text, const std::string& source);
/// Reads and parses a filter CSV file.
FilterSet read_filters_csv(const std::filesystem::path& path);
/// Writes `f` as a filter CSV (through a temporary renamed into place); UsageError, nothing written, for what
/// parse_filters_csv would refuse (names empty or with commas or control characters, wavelengths that do not
/// increase, transmissions outside [0, 1], rows of the wrong length).
void write_filters_csv(const std::filesystem::path& path, const FilterSet& f);
/// InputError naming `source` unless the set has filters, its curves are in [0, 1], its tabulation covers
/// [bands.front(), bands.back()] and every filter passes some light there.
void check_filters(const FilterSet& f, std::span<const double> bands, const std::string& source);
/// Largest |second difference| of any curve per nm^2 over its peak (0 for straight lines): a smoothness measure.
double filter_roughness(const FilterSet& f);

/// The forward model on the bands: A[k][b] = integral of T_k(l) s(l) P_d(l) hat_b(l), with s the light (times the
/// camera's response when known), hat_b the band's hat function (a spectrum is linear between bands and constant
/// beyond them) and P_d the d-th Legendre polynomial over the bands' range; one K x B matrix per d < terms.
std::vector<Eigen::MatrixXd> filter_system(const FilterSet& f, std::span<const double> bands, const Tabulated& s,
                                           int terms);

/// A filter capture's spectral calibration: responses R_k = T_k L sum_d a_kd P_d fitted on targets.
struct FilterCalibration {
  Eigen::MatrixXd response;  ///< a: K x terms
  Eigen::MatrixXd system;    ///< A = sum_d a_d A_d: K x B, readings of a spectrum on the bands
  Eigen::MatrixXd recovery;  ///< B x K: spectrum = recovery * readings
};

/// Fits a (per filter, least squares of minimum norm over the targets, terms the targets cannot separate dropped) so
/// that measured(i, k) = sum_d a_kd A_d[k] . reflectance(i), with A_d from filter_system(terms). measured: targets x K;
/// reflectance: targets x B. UsageError for sizes; InputError for a filter with no signal on the targets.
Eigen::MatrixXd fit_filter_response(const std::vector<Eigen::MatrixXd>& system, const Eigen::MatrixXd& measured,
                                    const Eigen::MatrixXd& reflectance);

/// The regularised solve in a basis: spectrum = U c with c = argmin |A U c - h|^2 + alpha |c|^2, U (B x r) the
/// basis orthonormalised, alpha = ridge * trace(U^T A^T A U) / r. Returns the B x K recovery matrix
/// U (U^T A^T A U + alpha I)^-1 U^T A^T. An empty basis means the identity (no constraint). UsageError for sizes
/// or a basis of rank 0.
Eigen::MatrixXd filter_recovery(const Eigen::MatrixXd& system, const Eigen::MatrixXd& basis, double ridge);

/// The linear minimum-mean-square-error (Wiener) solve with the spectra's second moment M (B x B) as prior and
/// independent reading noise of standard deviation noise[k] (readings' units): the B x K recovery
/// M A^T (A M A^T + diag(noise^2))^-1. Exact for spectra in M's range without noise. UsageError for sizes or
/// negative noise.
Eigen::MatrixXd filter_wiener_recovery(const Eigen::MatrixXd& system, const Eigen::MatrixXd& second_moment,
                                       const Eigen::VectorXd& noise);

/// The Wiener solve's posterior covariance (B x B) in the prior's units: M - R A M with R its recovery
/// (filter_wiener_recovery's arguments and checks). nonnegative_spectrum's metric.
Eigen::MatrixXd filter_wiener_posterior(const Eigen::MatrixXd& system, const Eigen::MatrixXd& second_moment,
                                        const Eigen::VectorXd& noise);

/// The ridge solve's posterior covariance up to a positive factor (B x B): U (U^T A^T A U + alpha I)^-1 U^T, the
/// covariance of c for a Gaussian prior on c that the ridge is the mean of (filter_recovery's arguments).
Eigen::MatrixXd filter_ridge_posterior(const Eigen::MatrixXd& system, const Eigen::MatrixXd& basis, double ridge);

/// A reflectance cannot be negative: replaces the linear estimate x (the posterior mean) by the most probable
/// spectrum of the Gaussian posterior of covariance `posterior` (B x B) with every band >= 0, i.e. the minimum of
/// (y - x)^T posterior^-1 (y - x) over y >= 0, by an active set on the bands held at zero (each step conditions the
/// posterior on them). x without negative bands is left as it is. UsageError for sizes.
void nonnegative_spectrum(const Eigen::MatrixXd& posterior, Eigen::Ref<Eigen::VectorXd> x);

/// Orthonormal columns spanning `columns` (B x n), dropping directions below 1e-10 of the largest.
Eigen::MatrixXd orthonormal_basis(const Eigen::MatrixXd& columns);

}  // namespace specula::acquire
