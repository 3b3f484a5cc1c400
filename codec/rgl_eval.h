#pragma once
// Evaluating an RGL material as Mitsuba 3's `measured` plugin (eval) and pbrt-v4's MeasuredBxDF (Sample_f) do, and
// turning it into a MERL-layout grid by evaluating it at every cell centre.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "specula/codec/merl.h"
#include "specula/codec/rgl_bsdf.h"
#include "specula/codec/rgl_warp.h"
#include "specula/store/store.h"

namespace specula::codec {

/// theta -> u = sqrt(2 theta / pi), the format's square coordinate of an elevation, and its inverse.
double rgl_theta_to_u(double theta);
double rgl_u_to_theta(double u);
/// phi -> v = (phi + pi) / (2 pi), and its inverse.
double rgl_phi_to_v(double phi);
double rgl_v_to_phi(double v);
/// Elevation of a unit vector as the renderers compute it, 2 asin(|d - z| / 2) (stable near the pole).
double rgl_elevation(const Eigen::Vector3d& d);

/// The stored values eval reads for one pair of directions: f(wi, wo)[c] = max(0, sum over k < n of weight[k] *
/// values[theta[k]][c][node[k]]), node = row * resolution + column; n = 0 when either direction is below the horizon.
struct RglStencil {
  std::array<std::uint32_t, 8> theta{}, node{};
  std::array<double, 8> weight{};
  int n = 0;
};

/// The tables of one material made into the renderers' interpolants.
class RglEvaluator {
 public:
  /// Builds the warps of `bsdf` (which from_tensor or the exporter has checked).
  explicit RglEvaluator(const RglBsdf& bsdf);

  std::size_t channels() const { return channels_; }
  /// f(wi, wo) in 1/sr per channel into out (channels() values): wi the tabulated (incident) direction; the renderers'
  /// value f cos(theta_o) = stored(vndf^-1(u_m)) D(u_m) / (4 sigma(u_wi)) divided by cos(theta_o), each channel
  /// clamped at 0 as pbrt-v4 does; all 0 when either direction is not above the horizon. Unit vectors, z the normal.
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const;
  /// eval as a linear map of the stored values (the factor D / (4 sigma cos(theta_o)) folded into the weights).
  RglStencil stencil(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const;
  /// The point of the sample square whose stored value eval interpolates for (wi, wo) (the inverse VNDF warp).
  Eigen::Vector2d sample_point(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const;
  /// D at the square point u (the ndf table), sigma at the square point of wi, and the vndf warp.
  double ndf(double u, double v) const;
  double sigma(double theta_i) const;
  const Warp2D& vndf() const { return vndf_; }
  /// The value rgl_merl_values holds at MERL cell `cell` (whose centre lies above the horizon) into out (channels()
  /// values): f at the centre with either direction tabulated, cosine-weighted.
  void merl_cell(std::size_t cell, std::span<double> out) const;
  /// The directional albedo (integral of f cos(theta_o) over the outgoing hemisphere) per channel at incident
  /// elevation theta_i, integrated over the sample square (n x n midpoints) through the vndf warp and its density.
  std::vector<double> albedo(double theta_i, std::size_t n = 128) const;

 private:
  struct Query {
    double params[2] = {0, 0};  // phi_i, theta_i
    WarpPoint s;                // the sample-square point
    double factor = 0;          // what eval multiplies the interpolated stored value by
  };
  Query locate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const;  // both above the horizon

  std::size_t channels_;
  bool jacobian_;
  Warp2D ndf_, sigma_, vndf_, values_;
};

/// The material evaluated by RglEvaluator::eval at every MERL cell centre (brdf::directions of merl_cell_centre) with
/// each of the cell's directions tabulated in turn, as a renderer meets the cell with the camera on either side:
/// (f(wi, wo) cos wo + f(wo, wi) cos wi) / (cos wi + cos wo), the renderers' products f cos summed over their cosines
/// (for a reciprocal file, f itself; the file's error is never divided by one grazing cosine alone). channels x 90 x
/// 90 x 180 values, channel slowest; -1 (no data) for cells whose centre is below the horizon. Parallel over
/// theta_h; the result does not depend on the thread count.
std::vector<float> rgl_merl_values(const RglBsdf& bsdf);
/// The tables of `bsdf` an export re-tabulates on (theta_i, phi_i, ndf, sigma, vndf, the sample grid's size), as a grid
/// keeps them (store::Grid::parameterisation).
store::GridParameterisation rgl_parameterisation(const RglBsdf& bsdf);
/// A spectral file as a grid on its own wavelengths, carrying its parameterisation; UsageError for an RGB file.
store::Grid rgl_to_grid(const RglBsdf& bsdf, const std::string& source);
/// An RGB file as a MERL BRDF; UsageError for a spectral file.
MerlBrdf rgl_to_merl(const RglBsdf& bsdf);

}  // namespace specula::codec
