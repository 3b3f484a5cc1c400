// specula synth-brdf: analytic spectral BRDFs (core/brdf_models.h) evaluated into a MERL-layout grid, as
// test and demonstration material with known ground truth. Each material's parameters are smooth functions
// of wavelength, so the grid is spectrally non-trivial.
#include <fmt/format.h>

#include <cmath>
#include <map>
#include <memory>

#include "apps/commands.h"
#include "apps/common.h"
#include "core/brdf_models.h"
#include "core/error.h"
#include "store/store.h"

namespace specula::app {
namespace {

struct SynthBrdfOptions {
  std::string material;
  std::string wavelengths = "420:720:10";
  std::string output;
  bool replace = false;
};

Eigen::VectorXd curve(const WavelengthGrid& g, auto&& f) {
  Eigen::VectorXd v(Eigen::Index(g.size()));
  for (std::size_t i = 0; i < g.size(); ++i) v[Eigen::Index(i)] = f(g.values()[i]);
  return v;
}
double step(double l, double at, double width) { return 1 / (1 + std::exp(-(l - at) / width)); }
double bump(double l, double mu, double sigma) { return std::exp(-0.5 * (l - mu) * (l - mu) / (sigma * sigma)); }
// Cauchy's dispersion of a clear coat: about 1.51 at 420 nm, 1.50 at 720 nm.
double coat(double l) { return 1.49 + 4200.0 / (l * l); }

const std::map<std::string, std::string>& materials() {
  static const std::map<std::string, std::string> m = {
      {"red-plastic", "Torrance-Sparrow, red diffuse under a dispersive clear coat, m = 0.12"},
      {"cyan-gloss", "Torrance-Sparrow, cyan diffuse, sharp coat, m = 0.05"},
      {"blue-paint", "isotropic Ward, blue diffuse, neutral specular, alpha = 0.08"},
      {"gold", "isotropic Ward, yellow metallic specular rising towards the red, alpha = 0.2"},
      {"green-matte", "Lambertian, green"}};
  return m;
}

std::unique_ptr<brdf::SpectralModel> make(const std::string& name, const WavelengthGrid& g) {
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(Eigen::Index(g.size()));
  if (name == "red-plastic")
    return std::make_unique<brdf::TorranceSparrow>(g, 0.12 * one, curve(g, coat),
                                                   curve(g, [](double l) { return 0.04 + 0.6 * step(l, 600, 15); }));
  if (name == "cyan-gloss")
    return std::make_unique<brdf::TorranceSparrow>(g, 0.05 * one, curve(g, coat), curve(g, [](double l) {
                                                     return 0.03 + 0.5 * (1 - step(l, 560, 20));
                                                   }));
  if (name == "blue-paint")
    return std::make_unique<brdf::Ward>(g, curve(g, [](double l) { return 0.04 + 0.45 * bump(l, 460, 40); }), 0.05 * one,
                                        0.08 * one);
  if (name == "gold")
    return std::make_unique<brdf::Ward>(g, 0.02 * one, curve(g, [](double l) { return 0.15 + 0.75 * step(l, 520, 25); }),
                                        0.2 * one);
  if (name == "green-matte")
    return std::make_unique<brdf::Lambertian>(g, curve(g, [](double l) { return 0.05 + 0.5 * bump(l, 540, 35); }));
  std::string names;
  for (const auto& [n, d] : materials()) names += (names.empty() ? "" : ", ") + n;
  throw UsageError("synth-brdf: unknown material '" + name + "'; choose one of " + names);
}

void run_synth_brdf(const SynthBrdfOptions& o) {
  const WavelengthGrid g = WavelengthGrid::parse(o.wavelengths);
  const auto model = make(o.material, g);
  store::Grid grid;
  grid.wavelengths = g;
  grid.brdf.resize(g.size() * brdf::kMerlCells);
  brdf::evaluate_grid(*model, grid.brdf);
  grid.provenance.importer = "synth-brdf " + o.material + ": " + materials().at(o.material);
  const std::string what = save_grid(grid, o.output, o.replace, "synth-brdf");
  fmt::print("wrote {} ({}, {}) as {}\n", o.material, materials().at(o.material), g.describe(), what);
}

}  // namespace

void setup_synth_brdf(CLI::App& app) {
  auto o = std::make_shared<SynthBrdfOptions>();
  auto* cmd = app.add_subcommand("synth-brdf", "An analytic spectral BRDF evaluated into a MERL-layout grid");
  std::string help = "Material:";
  for (const auto& [n, d] : materials()) help += " " + n + " (" + d + ");";
  cmd->add_option("material", o->material, help)->required();
  cmd->add_option("--wavelengths", o->wavelengths, "Band grid FIRST:LAST:STEP")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "STORE.h5:GRID, a .spgrid file, or an RGB .binary")->required();
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->callback([o] { run_synth_brdf(*o); });
}

}  // namespace specula::app
