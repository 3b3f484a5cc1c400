#pragma once
// An analytic BRDF fitted to scattered samples: a Lambertian term plus one or two microfacet lobes (GGX or
// Beckmann normal distribution, Smith height-correlated or V-groove shadowing, Schlick or dielectric Fresnel), each
// term with its own albedo per band. The albedos enter linearly once the lobes' shapes (roughness and Fresnel
// parameter) are fixed, so the fit is a variable projection: Levenberg-Marquardt (Eigen) over the few shape parameters,
// and for every trial shape a non-negative least-squares solve for the albedos. Robust by iteratively
// reweighted least squares with Huber weights on relative residuals (docs/resampling.md, "Model fit").
#include <Eigen/Core>
#include <span>
#include <string_view>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_models.h"

namespace specula::acquire {

enum class Distribution { ggx, beckmann };
enum class Shadowing { smith, vgroove };
enum class FresnelKind { schlick, dielectric };

/// The functional form of a microfacet lobe.
struct LobeKind {
  Distribution distribution = Distribution::ggx;
  Shadowing shadowing = Shadowing::smith;  ///< Smith height-correlated, or Torrance-Sparrow's V-groove
  FresnelKind fresnel = FresnelKind::schlick;
};

/// Parses "ggx" or "beckmann"; UsageError naming the choices otherwise.
Distribution parse_distribution(std::string_view name);
/// "ggx" or "beckmann".
std::string_view distribution_name(Distribution d);
/// Parses "schlick" or "dielectric"; UsageError naming the choices otherwise.
FresnelKind parse_fresnel(std::string_view name);
/// "schlick" or "dielectric".
std::string_view fresnel_name(FresnelKind f);
/// Parses "smith" or "vgroove"; UsageError naming the choices otherwise.
Shadowing parse_shadowing(std::string_view name);
/// "smith" or "vgroove".
std::string_view shadowing_name(Shadowing s);

/// One microfacet lobe's shape: roughness alpha (> 0) and the Fresnel parameter (Schlick: F0 in (0, 1];
/// dielectric: the relative index of refraction eta > 1).
struct LobeShape {
  double alpha = 0.1;
  double fresnel = 0.04;
};

/// The value of a lobe of unit albedo, D G F / (4 cos(theta_i) cos(theta_o)) in 1/sr, at unit directions wi, wo
/// (z the normal); 0 when either is at or below the horizon.
double microfacet_lobe(const LobeKind& kind, const LobeShape& s, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo);

/// f = diffuse / pi + sum_j specular_j * lobe_j per band.
class MicrofacetBrdf final : public brdf::SpectralModel {
 public:
  /// diffuse: bands values; shapes and specular (one albedo vector of bands values per lobe) of equal length 1 or 2;
  /// UsageError for other sizes, negative albedos or shapes outside their ranges.
  MicrofacetBrdf(WavelengthGrid grid, const LobeKind& kind, Eigen::VectorXd diffuse, std::vector<LobeShape> shapes,
                 std::vector<Eigen::VectorXd> specular);
  using SpectralModel::eval;
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const override;

  const LobeKind& kind() const { return kind_; }
  const Eigen::VectorXd& diffuse() const { return diffuse_; }
  const std::vector<LobeShape>& shapes() const { return shapes_; }
  const std::vector<Eigen::VectorXd>& specular() const { return specular_; }

 private:
  LobeKind kind_;
  Eigen::VectorXd diffuse_;
  std::vector<LobeShape> shapes_;
  std::vector<Eigen::VectorXd> specular_;
};

/// How a model is fitted.
struct ModelFitOptions {
  LobeKind kind;
  std::size_t lobes = 1;            ///< 1 or 2
  std::size_t shape_channels = 4;   ///< the shape fit sees the bands averaged in this many groups (at most bands)
  std::size_t shape_cells = 60000;  ///< at most this many cells in the shape fit (bright cells kept preferentially)
  std::size_t irls_rounds = 4;      ///< reweighting rounds (1: plain weighted least squares)
  double huber = 1.345;             ///< Huber threshold in robust standard deviations (1.4826 MAD)
};

/// What a fit did.
struct ModelFitReport {
  std::size_t observed_cells = 0;  ///< cells the albedos were fitted to
  std::size_t shape_cells = 0;     ///< cells the shape fit saw
  std::size_t evaluations = 0;     ///< variable-projection residual evaluations (LM, its numerical Jacobian, starts)
  double downweighted = 0;         ///< fraction of (cell, band) residuals the final round gave a Huber weight < 1
  double relative_rms = 0;         ///< sqrt of the count-weighted mean squared relative residual, final round
};

/// Fits the model to obs (values in 1/sr on `bands`, weights the samples per cell; cells index valid_cells()).
/// UsageError for bad options or sizes; InputError for fewer observed cells than 4 x the unknowns per band.
MicrofacetBrdf fit_model(const PriorObservations& obs, const WavelengthGrid& bands, const ModelFitOptions& o,
                         ModelFitReport* report = nullptr);

}  // namespace specula::acquire
