// specula uplift (reference Appendix A): an RGB MERL BRDF turned into a spectral grid, cell by cell, by the
// regularised least squares of eq A.3 (then clamping, or bounded to non-negative values), into a standalone
// grid file or a store.
#include <fmt/format.h>

#include <chrono>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/merl.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/uplift.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/store/io/exr.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct UpliftOptions {
  std::string input;
  std::string output;
  std::string store;
  std::string name;
  std::string wavelengths = "400:700:10";
  std::string illuminant = "D65";
  double alpha = codec::kDefaultUpliftAlpha;
  bool nonnegative = false;
  bool replace = false;
};

// An RGB lat-long environment map (linear sRGB primaries) to a spectral EXR of emission: each pixel by the same
// least squares, with an equal-energy white so that RGB (1, 1, 1) becomes a flat spectrum.
void uplift_environment(const UpliftOptions& o) {
  if (o.output.empty() || std::filesystem::path(o.output).extension() != ".exr")
    throw UsageError("uplift: an EXR environment map is written as a spectral EXR: give -o OUT.exr");
  const WavelengthGrid grid = WavelengthGrid::parse(o.wavelengths);
  const codec::Uplift uplift(codec::rgb_weights(grid, Eigen::VectorXd::Ones(Eigen::Index(grid.size()))), o.alpha);
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t w = 0, h = 0;
  const std::vector<float> rgb = store::read_exr_rgb(o.input, w, h);
  store::Cube cube;
  cube.wavelengths = grid;
  cube.resize(h, w, grid.size());
  cube.units = "radiance";
  std::size_t constrained = 0;
  try {
    constrained = codec::uplift_image(
        rgb, w, h, uplift, o.nonnegative ? codec::UpliftMethod::nonnegative : codec::UpliftMethod::clamp, cube.data);
  } catch (const InputError& e) {
    throw InputError(o.input + ": " + e.what());
  }
  store::write_spectral_exr(o.output, cube);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fmt::print("uplifted the {}x{} environment {} to {} ({}, alpha {}, {}) in {:.2f} s; {} pixels {}\n", w, h, o.input,
             o.output, grid.describe(), o.alpha, o.nonnegative ? "non-negative" : "clamped", seconds, constrained,
             o.nonnegative ? "met the bound x >= 0" : "had negative values clamped");
}

void run_uplift(const UpliftOptions& o) {
  if (std::filesystem::path(o.input).extension() == ".exr") return uplift_environment(o);
  if (o.output.empty() == o.store.empty())
    throw UsageError("uplift: give either -o FILE (a grid file) or --store STORE --name NAME, not both or neither");
  if (!o.store.empty() && o.name.empty()) throw UsageError("uplift: --store needs --name for the grid");
  if (!o.store.empty()) store::validate_name(o.name, "grid");
  const WavelengthGrid grid = WavelengthGrid::parse(o.wavelengths);
  const Eigen::VectorXd illum = parse_illuminant(o.illuminant, grid);
  const codec::Uplift uplift(codec::rgb_weights(grid, illum), o.alpha);

  const auto t0 = std::chrono::steady_clock::now();
  const codec::MerlBrdf rgb = codec::read_merl(o.input);
  codec::UpliftReport report;
  store::Grid g = codec::uplift_merl(
      rgb, grid, uplift, o.nonnegative ? codec::UpliftMethod::nonnegative : codec::UpliftMethod::clamp, &report);
  g.provenance.source_file = o.input;
  g.provenance.importer = o.nonnegative ? "uplift-nonnegative" : "uplift-clamp";
  g.provenance.command_line = command_line();
  if (!o.output.empty()) {
    codec::write_grid_file(o.output, g);
  } else {
    store::StoreWriter writer(o.store, {.compression = {}, .replace = o.replace, .command_line = command_line()});
    writer.add_grid(o.name, g);
    writer.commit();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fmt::print(
      "uplifted {} cells of {} to {} ({}, alpha {}, {}) in {:.2f} s; {} cells {}; max RGB error {:.2e} of the "
      "cell's largest channel\n",
      report.cells, o.input, o.output.empty() ? o.store + ":" + o.name : o.output, grid.describe(), o.alpha,
      o.nonnegative ? "non-negative" : "clamped", seconds, report.constrained,
      o.nonnegative ? "met the bound x >= 0" : "had negative values clamped", report.max_rgb_error);
}

}  // namespace

void setup_uplift(CLI::App& app) {
  auto o = std::make_shared<UpliftOptions>();
  auto* cmd = app.add_subcommand(
      "uplift",
      "RGB MERL BRDF (.binary) or RGB EXR environment map to spectra by regularised least squares (Appendix A)");
  cmd->add_option("input", o->input, "MERL .binary file, or an RGB EXR environment map (written as a spectral EXR)")
      ->required();
  cmd->add_option("-o,--output", o->output, "Spectral grid file to write (docs/grid-format.md)");
  cmd->add_option("--store", o->store, "Store to add the grid to instead (created if absent)");
  cmd->add_option("--name", o->name, "Grid name in the store");
  cmd->add_option("--wavelengths", o->wavelengths, "Output bands, FIRST:LAST:STEP or a list")->capture_default_str();
  cmd->add_option("--illuminant", o->illuminant,
                  "Illuminant under which RGB was seen: D65, D50, A, E, D<CCT>, blackbody:K or a CSV file")
      ->capture_default_str();
  cmd->add_option("--alpha", o->alpha, "Weight of the second differences in eq A.3 (larger: smoother, looser RGB fit)")
      ->capture_default_str();
  cmd->add_flag("--nonnegative", o->nonnegative, "Solve eq A.3 subject to x >= 0 instead of clamping afterwards");
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->callback([o] { run_uplift(*o); });
}

}  // namespace specula::app
