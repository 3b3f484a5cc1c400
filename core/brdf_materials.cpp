#include "specula/core/brdf_materials.h"

#include <cmath>

#include "specula/core/error.h"

namespace specula::brdf {
namespace {

Eigen::VectorXd curve(const WavelengthGrid& g, auto&& f) {
  Eigen::VectorXd v(Eigen::Index(g.size()));
  for (std::size_t i = 0; i < g.size(); ++i) v[Eigen::Index(i)] = f(g.values()[i]);
  return v;
}
double step(double l, double at, double width) { return 1 / (1 + std::exp(-(l - at) / width)); }
double bump(double l, double mu, double sigma) { return std::exp(-0.5 * (l - mu) * (l - mu) / (sigma * sigma)); }
// Cauchy's dispersion of a clear coat: about 1.51 at 420 nm, 1.50 at 720 nm.
double coat(double l) { return 1.49 + 4200.0 / (l * l); }

}  // namespace

const std::map<std::string, std::string>& material_catalogue() {
  static const std::map<std::string, std::string> m = {
      {"red-plastic", "Torrance-Sparrow, red diffuse under a dispersive clear coat, m = 0.12"},
      {"cyan-gloss", "Torrance-Sparrow, cyan diffuse, sharp coat, m = 0.05"},
      {"blue-paint", "isotropic Ward, blue diffuse, neutral specular, alpha = 0.08"},
      {"gold", "isotropic Ward, yellow metallic specular rising towards the red, alpha = 0.2"},
      {"green-matte", "Lambertian, green"},
      {"study-ts", "the reference's Torrance-Sparrow test (§5.4.1), grey: glossy m = 0.2, eta = 1.5, rho_d = 0.1"},
      {"study-ward", "the reference's isotropic Ward test (§5.4.2), grey: specular only, rho_s = 0.3, alpha = 0.07"}};
  return m;
}

std::unique_ptr<SpectralModel> make_material(const std::string& name, const WavelengthGrid& g) {
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(Eigen::Index(g.size()));
  if (name == "red-plastic")
    return std::make_unique<TorranceSparrow>(g, 0.12 * one, curve(g, coat),
                                             curve(g, [](double l) { return 0.04 + 0.6 * step(l, 600, 15); }));
  if (name == "cyan-gloss")
    return std::make_unique<TorranceSparrow>(g, 0.05 * one, curve(g, coat),
                                             curve(g, [](double l) { return 0.03 + 0.5 * (1 - step(l, 560, 20)); }));
  if (name == "blue-paint")
    return std::make_unique<Ward>(g, curve(g, [](double l) { return 0.04 + 0.45 * bump(l, 460, 40); }), 0.05 * one,
                                  0.08 * one);
  if (name == "gold")
    return std::make_unique<Ward>(g, 0.02 * one, curve(g, [](double l) { return 0.15 + 0.75 * step(l, 520, 25); }),
                                  0.2 * one);
  if (name == "green-matte")
    return std::make_unique<Lambertian>(g, curve(g, [](double l) { return 0.05 + 0.5 * bump(l, 540, 35); }));
  if (name == "study-ts") return std::make_unique<TorranceSparrow>(g, 0.2 * one, 1.5 * one, 0.1 * one);
  if (name == "study-ward") return std::make_unique<Ward>(g, 0.0 * one, 0.3 * one, 0.07 * one);
  std::string names;
  for (const auto& [n, d] : material_catalogue()) names += (names.empty() ? "" : ", ") + n;
  throw UsageError("unknown material '" + name + "'; choose one of " + names);
}

}  // namespace specula::brdf
