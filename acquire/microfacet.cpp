// The microfacet model of acquire/model_fit.h: its lobes and its spectral evaluation.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "specula/acquire/model_fit.h"
#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// Smith's Lambda of a direction at cos(theta) = c for the distribution of roughness alpha (Walter et al. 2007;
// the Beckmann one in its rational approximation).
double smith_lambda(Distribution d, double alpha, double c) {
  const double tan2 = std::max(0.0, 1 - c * c) / (c * c);
  if (tan2 == 0) return 0;
  if (d == Distribution::ggx) return 0.5 * (std::sqrt(1 + alpha * alpha * tan2) - 1);
  const double a = 1 / (alpha * std::sqrt(tan2));
  return a >= 1.6 ? 0.0 : (1 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a);
}

double normal_distribution(Distribution d, double alpha, double cos_h) {
  const double c2 = cos_h * cos_h, tan2 = std::max(0.0, 1 - c2) / c2, a2 = alpha * alpha;
  if (d == Distribution::ggx) return a2 / (pi * c2 * c2 * (a2 + tan2) * (a2 + tan2));
  return std::exp(-tan2 / a2) / (pi * a2 * c2 * c2);
}

void check_shape(FresnelKind f, const LobeShape& s) {
  if (!(std::isfinite(s.alpha) && s.alpha > 0))
    throw UsageError("microfacet model: roughness alpha is " + num(s.alpha) + "; it must be > 0");
  const bool ok =
      f == FresnelKind::schlick ? s.fresnel > 0 && s.fresnel <= 1 : s.fresnel > 1 && std::isfinite(s.fresnel);
  if (!ok)
    throw UsageError("microfacet model: Fresnel parameter " + num(s.fresnel) +
                     (f == FresnelKind::schlick ? " (Schlick F0) must be in (0, 1]" : " (dielectric eta) must be > 1"));
}

}  // namespace

Distribution parse_distribution(std::string_view name) {
  if (name == "ggx") return Distribution::ggx;
  if (name == "beckmann") return Distribution::beckmann;
  throw UsageError("unknown microfacet distribution '" + std::string(name) + "'; choose ggx or beckmann");
}

std::string_view distribution_name(Distribution d) { return d == Distribution::ggx ? "ggx" : "beckmann"; }

FresnelKind parse_fresnel(std::string_view name) {
  if (name == "schlick") return FresnelKind::schlick;
  if (name == "dielectric") return FresnelKind::dielectric;
  throw UsageError("unknown Fresnel term '" + std::string(name) + "'; choose schlick or dielectric");
}

std::string_view fresnel_name(FresnelKind f) { return f == FresnelKind::schlick ? "schlick" : "dielectric"; }

Shadowing parse_shadowing(std::string_view name) {
  if (name == "smith") return Shadowing::smith;
  if (name == "vgroove") return Shadowing::vgroove;
  throw UsageError("unknown shadowing term '" + std::string(name) + "'; choose smith or vgroove");
}

std::string_view shadowing_name(Shadowing s) { return s == Shadowing::smith ? "smith" : "vgroove"; }

double microfacet_lobe(const LobeKind& kind, const LobeShape& s, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const double ci = wi.z(), co = wo.z();
  if (ci <= 0 || co <= 0) return 0;
  const Eigen::Vector3d h = (wi + wo).normalized();
  const double cos_d = std::clamp(wi.dot(h), 1e-12, 1.0);
  const double fr = kind.fresnel == FresnelKind::schlick ? s.fresnel + (1 - s.fresnel) * std::pow(1 - cos_d, 5)
                                                         : brdf::fresnel_dielectric(std::acos(cos_d), s.fresnel);
  const Distribution d = kind.distribution;
  const double g = kind.shadowing == Shadowing::smith
                       ? 1 / (1 + smith_lambda(d, s.alpha, ci) + smith_lambda(d, s.alpha, co))
                       : std::min({1.0, 2 * h.z() * ci / cos_d, 2 * h.z() * co / cos_d});
  return normal_distribution(d, s.alpha, h.z()) * g * fr / (4 * ci * co);
}

MicrofacetBrdf::MicrofacetBrdf(WavelengthGrid grid, const LobeKind& kind, Eigen::VectorXd diffuse,
                               std::vector<LobeShape> shapes, std::vector<Eigen::VectorXd> specular)
    : SpectralModel(std::move(grid)),
      kind_(kind),
      diffuse_(std::move(diffuse)),
      shapes_(std::move(shapes)),
      specular_(std::move(specular)) {
  const auto b = Eigen::Index(bands());
  if (shapes_.empty() || shapes_.size() > 2 || specular_.size() != shapes_.size())
    throw UsageError("microfacet model: give 1 or 2 lobes, each with a shape and a specular albedo");
  if (diffuse_.size() != b || (diffuse_.array() < 0).any() || !diffuse_.allFinite())
    throw UsageError("microfacet model: the diffuse albedo needs " + std::to_string(b) + " values >= 0");
  for (std::size_t j = 0; j < shapes_.size(); ++j) {
    check_shape(kind_.fresnel, shapes_[j]);
    if (specular_[j].size() != b || (specular_[j].array() < 0).any() || !specular_[j].allFinite())
      throw UsageError("microfacet model: specular albedo " + std::to_string(j + 1) + " needs " + std::to_string(b) +
                       " values >= 0");
  }
}

void MicrofacetBrdf::eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const {
  if (out.size() != bands())
    throw UsageError("BRDF evaluation: output has " + std::to_string(out.size()) + " values for " +
                     std::to_string(bands()) + " bands");
  const bool above = wi.z() > 0 && wo.z() > 0;
  double lobe[2] = {0, 0};
  for (std::size_t j = 0; j < shapes_.size() && above; ++j) lobe[j] = microfacet_lobe(kind_, shapes_[j], wi, wo);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const auto e = Eigen::Index(k);
    double v = above ? diffuse_[e] / pi : 0.0;
    for (std::size_t j = 0; j < shapes_.size(); ++j) v += specular_[j][e] * lobe[j];
    out[k] = v;
  }
}

}  // namespace specula::acquire
