#pragma once
// A BRDF on the MERL grid (spectral grid or RGB MERL) as an isotropic RGL material (codec/rgl_bsdf.h), built as
// Dupuy and Jakob (2018) build theirs from a measurement: the microfacet distribution D recovered from the
// retro-reflection by power iteration (Dupuy et al. 2015, D_{n+1}(theta) = f(k, k) cos(theta) sigma_n(theta)),
// sigma(theta) = integral of D(m) <k . m>+ dm by quadrature, D scaled so sigma(0) = 1, the incident elevations chosen
// uniformly in sigma, per elevation a vndf table on the square (u, v) led by the visible-normal density D(m) <wi . m>+
// (RglExportSettings), and at the nodes of the sample square warped by it the values f cos(theta_o) 4 sigma / D,
// then refitted by least squares so that the renderers' interpolation of them matches f at every MERL cell
// (codec/rgl_fit.h). f between MERL cells is interpolated trilinearly in the grid's index space over the cells that
// hold data.
// A grid imported from an RGL file keeps that file's parameterisation (store::Grid::parameterisation); an export at
// the file's size then tabulates on it (its theta_i, ndf and sigma as they are, its vndf at most vndf_resolution
// nodes per side) and only fits the values.
#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <string>

#include "specula/codec/merl.h"
#include "specula/codec/rgl_bsdf.h"
#include "specula/codec/rgl_fit.h"
#include "specula/store/store.h"

namespace specula::codec {

/// Which tables an export tabulates the BRDF on.
enum class RglParameterisation {
  automatic,  ///< the grid's source parameterisation when it carries one and the sizes asked are its own (or 0)
  source,     ///< the grid's source parameterisation; UsageError when it carries none or other sizes are asked
  estimate,   ///< built from the BRDF alone (D from the retro-reflection, sigma, theta_i uniform in sigma, vndf)
};
/// "auto", "source", "estimate".
const char* rgl_parameterisation_name(RglParameterisation p);
/// The parameterisation named by rgl_parameterisation_name; UsageError for another name.
RglParameterisation parse_rgl_parameterisation(const std::string& name);

/// The resolution of an exported file; the defaults follow the published RGL files except the ndf nodes and the vndf
/// table (see docs/brdf.md: 181 ndf nodes put one at every MERL theta_h cell centre; a 32 x 32 vndf keeps a 31-band
/// file near 1 MB, where the published files use 128 x 128).
struct RglExportSettings {
  std::size_t theta_i = 8;      ///< incident elevations, >= 2; 0: the grid's source's if it has one, else 8
  std::size_t resolution = 32;  ///< sample-square nodes per side, >= 2; 0: the source's if any, else 32
  std::size_t ndf_nodes = 181;  ///< nodes of the ndf and sigma tables in u, >= 2
  /// vndf nodes per side, >= 2; on the source's tables, the most per side (a larger source vndf is resampled so that
  /// its warp follows the source's, resample_density)
  std::size_t vndf_resolution = 32;
  std::size_t power_iterations = 30;
  /// The vndf table only places the sample nodes (stored values use the ndf) and guides the renderers' sampling. Per
  /// incident direction it is the mixture (1 - vndf_uniform) p + vndf_uniform q, both normalised over the table's
  /// nodes: p = (D(0) (D(m) / D(0))^vndf_exponent + vndf_floor / pi) <wi . m>+ (times the square's Jacobian), q
  /// uniform over the nodes with wi . m > 0. The exponent, the floor and the uniform part keep nodes on the shoulder,
  /// the diffuse part and the tail of a glossy material, which the peak would otherwise take (bench/brdf-formats,
  /// docs/brdf.md: 0.7, 0.3 and 0.3).
  double vndf_exponent = 0.7;
  double vndf_floor = 0.3;
  double vndf_uniform = 0.3;
  /// The stored values: the least-squares fit to the BRDF at every MERL cell (codec/rgl_fit.h), or without it the
  /// point samples at the nodes (which the fit starts from).
  bool least_squares = true;
  RglFitSettings fit;
  std::string description;  ///< empty: "specula export"
  RglParameterisation parameterisation = RglParameterisation::automatic;
};

/// The parameterisation an export of a grid carrying `source` (nullptr: none) uses under `settings`: source or
/// estimate (automatic resolved); UsageError when `source` is asked and the grid carries none or other sizes are asked.
RglParameterisation rgl_parameterisation_used(const store::GridParameterisation* source,
                                              const RglExportSettings& settings);

/// A spectral grid as a spectral file on the grid's wavelengths (luminance: CIE Y under D65 as sRGB's luminance), on
/// the parameterisation rgl_parameterisation_used picks for grid.parameterisation. UsageError for settings out of
/// range.
RglBsdf export_rgl(const store::Grid& grid, const RglExportSettings& settings);
/// An RGB MERL BRDF as an RGB file (luminance 0.2126 R + 0.7152 G + 0.0722 B), on the parameterisation
/// rgl_parameterisation_used picks for `source` (the grid the BRDF was made from, or nullptr).
RglBsdf export_rgl(const MerlBrdf& brdf, const RglExportSettings& settings,
                   const store::GridParameterisation* source = nullptr);

/// The microfacet tables of an export, at the nodes u_k = k / (n - 1) (theta = u^2 pi / 2) of the ndf table.
struct RglMicrofacet {
  std::vector<double> ndf, sigma;  ///< D and sigma, scaled so that sigma(0) = 1
};
/// D and sigma as export_rgl builds them from `values` (channels x MERL cells, channel slowest, negative: no data)
/// times `scale`: D by rgl_ndf_from_retro from the luminance (`lum_weights` per channel) of the retro-reflection
/// (theta_d = 0, interpolated as between any cells) at settings.ndf_nodes nodes. UsageError for sizes that disagree.
RglMicrofacet rgl_microfacet(std::span<const float> values, std::size_t channels, double scale,
                             std::span<const double> lum_weights, const RglExportSettings& settings);
/// n >= 2 incident elevations uniform in sigma (a table at nodes uniform in u, read linearly) from theta = 0 to pi/2,
/// strictly ascending in float, as export_rgl places them.
std::vector<float> rgl_theta_i(std::span<const double> sigma, std::size_t n);

/// The vndf table export_rgl writes for incident elevation theta_i (vndf_resolution^2 values, rows in phi) from D at
/// nodes uniform in u (read linearly): the mixture of RglExportSettings; with vndf_exponent 1, vndf_floor 0 and
/// vndf_uniform 0, the visible-normal density D(m) <wi . m>+ times the square's Jacobian, as the published files hold.
std::vector<float> rgl_vndf(std::span<const double> ndf, double theta_i, const RglExportSettings& settings);

/// The pieces of the construction, exposed for tests: D at ndf_nodes nodes u_k = k / (n - 1) (theta = u^2 pi / 2)
/// from the retro-reflection `retro` (values at those nodes), normalised so that sigma(0) = 1.
std::vector<double> rgl_ndf_from_retro(std::span<const double> retro, std::size_t iterations);
/// sigma(theta) = integral over the hemisphere of D(m) max(0, k . m) dm for the D tabulated at nodes u_k and linear in
/// u between them, at each elevation of `theta`.
std::vector<double> rgl_sigma(std::span<const double> ndf, std::span<const double> theta);

}  // namespace specula::codec
