#pragma once
// Spectral calibration and recovery (reference §4.1.3-4.1.6): the system's response R_j(lambda) to each LCTF
// tuning is modelled as a weighted Dirac delta (eq 4.4) or as the manufacturer's transmission curve times a
// constant (eq 4.6), fitted on images of diffuse targets of known reflectance (eqs 4.3, 4.5); reflectance is
// recovered per pixel by the Nystrom method (eq 4.7), f = (R L)^-1 H.
#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

namespace specula::acquire {

/// delta (eq 4.4), factored (eq 4.6), or broadband filters (acquire/filters.h).
enum class SpectralModel { delta, factored, filters };

/// "delta" or "factored"; UsageError otherwise.
SpectralModel parse_spectral_model(const std::string& name);

/// A tabulated curve (nm, value) with linear interpolation, constant beyond its ends.
struct Tabulated {
  std::vector<double> nm, value;
  double at(double l) const;
};

/// A fitted spectral calibration: f = recovery * H, with H the HDR values of the N bands (flat-field corrected).
struct SpectralCalibration {
  SpectralModel model = SpectralModel::delta;
  std::vector<double> bands;  ///< tuning wavelengths (nm)
  Eigen::VectorXd scale;      ///< w_j (delta), c_j (factored) or the filters' response terms a_kd (row-major)
  Eigen::MatrixXd recovery;   ///< (R L)^-1, N x N; for filters B x K (filter_recovery)
  /// filters: the solve's posterior covariance (B x B; nonnegative_spectrum's metric); empty: the linear recovery
  Eigen::MatrixXd posterior;
  /// filters, Wiener: each filter's reading noise relative to its white reading, as the solve assumed; else empty
  Eigen::VectorXd noise;
};

/// Fits the delta model: H_ij = w_j L(lambda_j) rho_i(lambda_j) by least squares over the targets used.
/// measured: targets x bands HDR values; reflectance: targets x bands. UsageError for sizes or no targets.
SpectralCalibration fit_delta(std::span<const double> bands, const Tabulated& light, const Eigen::MatrixXd& measured,
                              const Eigen::MatrixXd& reflectance);
/// Fits the factored model: H_ij = c_j integral of T_j L rho_i over transmission[j]'s grid (rho_i linearly
/// interpolated between bands), then builds R L for the Nystrom system with f piecewise linear between bands.
SpectralCalibration fit_factored(std::span<const double> bands, const Tabulated& light,
                                 std::span<const Tabulated> transmission, const Eigen::MatrixXd& measured,
                                 const Eigen::MatrixXd& reflectance);

/// Eq 4.8: root mean square difference of two spectra on the same bands.
double spectral_rms(const Eigen::VectorXd& a, const Eigen::VectorXd& b);

}  // namespace specula::acquire
