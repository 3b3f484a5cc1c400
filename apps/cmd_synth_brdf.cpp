// specula synth-brdf: analytic spectral BRDFs (core/brdf_models.h) evaluated into a MERL-layout grid, as
// test and demonstration material with known ground truth. Each material's parameters are smooth functions
// of wavelength, so the grid is spectrally non-trivial.
#include <fmt/format.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct SynthBrdfOptions {
  std::string material;
  std::string wavelengths = "420:720:10";
  std::string output;
  bool replace = false;
};

void run_synth_brdf(const SynthBrdfOptions& o) {
  const WavelengthGrid g = WavelengthGrid::parse(o.wavelengths);
  const auto model = brdf::make_material(o.material, g);
  store::Grid grid;
  grid.wavelengths = g;
  grid.brdf.resize(g.size() * brdf::kMerlCells);
  brdf::evaluate_grid(*model, grid.brdf);
  grid.provenance.importer = "synth-brdf " + o.material + ": " + brdf::material_catalogue().at(o.material);
  const std::string what = save_grid(grid, o.output, o.replace, "synth-brdf");
  fmt::print("wrote {} ({}, {}) as {}\n", o.material, brdf::material_catalogue().at(o.material), g.describe(), what);
}

}  // namespace

void setup_synth_brdf(CLI::App& app) {
  auto o = std::make_shared<SynthBrdfOptions>();
  auto* cmd = app.add_subcommand("synth-brdf", "An analytic spectral BRDF evaluated into a MERL-layout grid");
  std::string help = "Material:";
  for (const auto& [n, d] : brdf::material_catalogue()) help += " " + n + " (" + d + ");";
  cmd->add_option("material", o->material, help)->required();
  cmd->add_option("--wavelengths", o->wavelengths, "Band grid FIRST:LAST:STEP")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "STORE.h5:GRID, a .spgrid file, or an RGB .binary")->required();
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->callback([o] { run_synth_brdf(*o); });
}

}  // namespace specula::app
