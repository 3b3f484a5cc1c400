#pragma once
// Analytic spectral BRDFs (reference chapter 5.4): Lambertian, Torrance-Sparrow (eq 5.11, with a spectral
// index of refraction through the Fresnel term) and the isotropic Ward model of Walter's notes (eq 5.12).
// Every parameter is given per band of a wavelength grid. Values are in 1/sr; directions below the horizon
// give 0. They are ground truth for tests of grids, codecs and resampling.
#include <Eigen/Core>
#include <span>

#include "specula/core/brdf_geometry.h"
#include "specula/core/wavelengths.h"

namespace specula::brdf {

/// A BRDF with one value per band of wavelengths().
class SpectralModel {
 public:
  virtual ~SpectralModel() = default;
  /// The grid the parameters (and so the values) are given on.
  const WavelengthGrid& wavelengths() const { return grid_; }
  std::size_t bands() const { return grid_.size(); }
  /// f(wi, wo) for every band into out (bands() values); unit vectors, z the normal; 0 if either z <= 0.
  virtual void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const = 0;
  /// eval at standard angles.
  void eval(const StdAngles& a, std::span<double> out) const;

 protected:
  explicit SpectralModel(WavelengthGrid grid);
  WavelengthGrid grid_;
};

/// f = rho / pi.
class Lambertian final : public SpectralModel {
 public:
  /// rho: one albedo in [0, 1] per band; throws UsageError otherwise.
  Lambertian(WavelengthGrid grid, Eigen::VectorXd rho);
  using SpectralModel::eval;
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const override;

 private:
  Eigen::VectorXd rho_;
};

/// Eq 5.11, f = rho_d / pi + D G F / (pi cos(theta_i) cos(theta_o)), with D = exp(-tan^2(theta_h) / m^2) /
/// (4 m^2 cos^4(theta_h)), the V-groove G and the unpolarised dielectric Fresnel F of the index eta.
class TorranceSparrow final : public SpectralModel {
 public:
  /// Per band: m > 0 (RMS slope), eta > 0 (relative index of refraction), rho_d in [0, 1]; else UsageError.
  TorranceSparrow(WavelengthGrid grid, Eigen::VectorXd m, Eigen::VectorXd eta, Eigen::VectorXd rho_d);
  using SpectralModel::eval;
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const override;

 private:
  Eigen::VectorXd m_, eta_, rho_d_;
};

/// Eq 5.12 with alpha_x = alpha_y = alpha, plus a Lambertian term: f = rho_d / pi + rho_s exp(-tan^2(theta_h) /
/// alpha^2) / (4 pi alpha^2 sqrt(cos(theta_i) cos(theta_o))).
class Ward final : public SpectralModel {
 public:
  /// Per band: rho_d, rho_s >= 0, alpha > 0; else UsageError.
  Ward(WavelengthGrid grid, Eigen::VectorXd rho_d, Eigen::VectorXd rho_s, Eigen::VectorXd alpha);
  using SpectralModel::eval;
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const override;

 private:
  Eigen::VectorXd rho_d_, rho_s_, alpha_;
};

/// Unpolarised Fresnel reflectance of a dielectric interface of relative index eta at incidence angle
/// theta (eq 5.11's F; the normal-incidence limit ((eta - 1) / (eta + 1))^2 at theta = 0; 1 beyond the critical angle).
double fresnel_dielectric(double theta, double eta);

/// Evaluates `model` at n scattered standard angles (n x 4 row-major: theta_i, phi_i, theta_o, phi_o) into
/// values (n x bands row-major); throws UsageError on mismatched sizes.
void evaluate_at(const SpectralModel& model, std::span<const double> angles, std::span<float> values);

/// Evaluates `model` at every MERL cell centre into grid (bands x 90 x 90 x 180, band slowest, as the store's
/// /grids/<name>/brdf); cells whose centre is below the horizon get -1 (no data). Throws UsageError on size.
void evaluate_grid(const SpectralModel& model, std::span<float> grid);

}  // namespace specula::brdf
