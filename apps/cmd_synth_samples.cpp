// specula synth-samples: scattered spectral BRDF samples of an analytic material (core/brdf_materials.h) or of a
// grid (looked up trilinearly by default, acquire/simulate.h) at the configurations of a simulated scan of the
// reference's rig (acquire/scan.h) or at random ones, appended to a store in batches as a capture would be. Ground
// truth for resampling tests, the study and the benchmarks.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/scan.h"
#include "specula/acquire/simulate.h"
#include "specula/acquire/synth_samples.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct SynthSamplesOptions {
  std::string material;
  std::string output;
  std::string geometry = "scan";
  std::size_t count = 0;
  acquire::ScanRig rig;
  std::optional<double> sphere_row;  // the image row of the sphere's centre, pixels
  std::string wavelengths = "420:720:10";
  std::uint64_t seed = 1;
  double noise = 0;
  std::string compression = "deflate";
  std::string lookup = "trilinear";
  bool replace = false;
  bool json = false;
};

void run_synth_samples(SynthSamplesOptions o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (o.sphere_row) {
    if (!std::isfinite(*o.sphere_row)) throw UsageError("--sphere-row: give a finite image row in pixels");
    o.rig.off_axis_y = *o.sphere_row * o.rig.distance / o.rig.focal_px;  // its projection focal * y / distance
  }
  const auto spec = store::parse_object_spec(o.output);
  if (!spec || spec->file.extension() != ".h5")
    throw UsageError("synth-samples: -o " + o.output + ": write the samples as STORE.h5:NAME");
  const std::string file = spec->file.string(), name = spec->name;
  store::validate_name(name, "samples");
  if (o.geometry != "scan" && o.geometry != "random")
    throw UsageError("--geometry '" + o.geometry + "': use scan (the reference's rig) or random");
  if (o.geometry == "random" && (o.count == 0 || o.count > (std::size_t(1) << 32) - 2))
    throw UsageError("--geometry random needs -n, 1 to 2^32 - 2 samples");
  if (o.geometry == "scan") acquire::check_rig(o.rig);
  if (!(o.noise >= 0 && o.noise <= 1)) throw UsageError("--noise must be a relative standard deviation from 0 to 1");
  if (o.lookup != "trilinear" && o.lookup != "nearest")
    throw UsageError("--lookup '" + o.lookup + "': use trilinear or nearest");
  const WavelengthGrid g = WavelengthGrid::parse(o.wavelengths);
  // A store grid (STORE.h5:GRID), a .spgrid or an RGB MERL .binary (uplifted onto the bands) instead of a named one.
  const bool is_grid =
      !brdf::material_catalogue().count(o.material) &&
      (store::parse_object_spec(o.material) || o.material.ends_with(".spgrid") || o.material.ends_with(".binary"));
  const auto model = is_grid
                         ? acquire::grid_material(
                               std::make_shared<const store::Grid>(load_grid(o.material, "synth-samples", g)), g,
                               o.lookup == "nearest" ? acquire::GridLookup::nearest : acquire::GridLookup::trilinear)
                         : brdf::make_material(o.material, g);
  const std::size_t b = g.size();

  store::StoreWriter writer(
      file,
      {.compression = store::Compression::parse(o.compression), .replace = o.replace, .command_line = command_line()});
  store::Provenance prov;
  prov.importer = fmt::format("synth-samples {} ({}) at {} configurations, noise {}", o.material,
                              is_grid ? "grid, " + o.lookup + " lookup" : brdf::material_catalogue().at(o.material),
                              o.geometry, o.noise);
  writer.create_samples(name, g, "1/sr", prov);
  const acquire::SynthesisCount made =
      acquire::synthesize_samples(*model,
                                  {.geometry = o.geometry == "scan" ? acquire::SampleSynthesis::Geometry::scan
                                                                    : acquire::SampleSynthesis::Geometry::random,
                                   .rig = o.rig,
                                   .count = o.count,
                                   .noise = o.noise,
                                   .seed = o.seed},
                                  [&](std::span<const double> angles, std::span<const float> values) {
                                    writer.append_samples(name, angles, values);
                                  });
  const std::size_t written = made.samples, pixels = made.pixels;
  writer.commit();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j;
    j["samples"] = written;
    j["bands"] = b;
    j["pixels"] = pixels;
    j["lights"] = o.geometry == "scan" ? o.rig.lights : 0;
    j["bytes"] = written * (32 + 4 * b);
    j["seconds"] = seconds;
    j["output"] = o.output;
    print_json(j);
    return;
  }
  fmt::print("wrote {} samples of {} ({}) at {} configurations{} to {} in {:.1f} s\n", written, o.material,
             g.describe(), o.geometry,
             o.geometry == "scan" ? fmt::format(" ({} sphere pixels x {} lights)", pixels, o.rig.lights) : "", o.output,
             seconds);
}

}  // namespace

void setup_synth_samples(CLI::App& app) {
  auto o = std::make_shared<SynthSamplesOptions>();
  auto* cmd = app.add_subcommand(
      "synth-samples",
      "Scattered samples of an analytic BRDF or a grid at a simulated scan's (or random) configurations");
  std::string help = "Material: STORE.h5:GRID, a .spgrid, an RGB MERL .binary (uplifted), or";
  for (const auto& [n, d] : brdf::material_catalogue()) help += " " + n + " (" + d + ");";
  cmd->add_option("material", o->material, help)->required();
  cmd->add_option("-o,--output", o->output, "STORE.h5:NAME")->required();
  cmd->add_option("--geometry", o->geometry, "scan (the reference's rig, computed directly) or random (uniform)")
      ->capture_default_str();
  cmd->add_option("-n", o->count, "random: number of samples; scan: thin evenly to at most this many");
  cmd->add_option("--sphere-px", o->rig.sphere_px, "scan: the sphere's diameter on the image (pixels)")
      ->capture_default_str();
  cmd->add_option("--sphere-row", o->sphere_row,
                  fmt::format("scan: the image row of the sphere's centre, pixels from the optical axis (pixel centres "
                              "at whole numbers + 0.5; default {:g}, a row boundary, which the specular path follows)",
                              o->rig.off_axis_y * o->rig.focal_px / o->rig.distance));
  cmd->add_option("--lights", o->rig.lights, "scan: light positions on the arc")->capture_default_str();
  cmd->add_option("--light-step", o->rig.light_step_deg, "scan: degrees between light positions")
      ->capture_default_str();
  cmd->add_option("--first-light", o->rig.first_light_deg, "scan: degrees between the camera and the first light")
      ->capture_default_str();
  cmd->add_option("--wavelengths", o->wavelengths, "Band grid FIRST:LAST:STEP")->capture_default_str();
  cmd->add_option("--noise", o->noise, "Relative Gaussian noise on every value (e.g. 0.02)")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the random configurations and the noise")->capture_default_str();
  cmd->add_option("--compression", o->compression, "none, deflate or deflate:LEVEL")->capture_default_str();
  cmd->add_option(
         "--lookup", o->lookup,
         "A grid material between cell centres: trilinear (in MERL index space) or nearest (BRDFRead.cpp's cell)")
      ->capture_default_str();
  cmd->add_flag("--replace", o->replace, "Replace samples of the same name");
  cmd->add_flag("--json", o->json, "Print one JSON object (samples, bands, pixels, lights, bytes, seconds)");
  cmd->callback([o] { run_synth_samples(*o); });
}

}  // namespace specula::app
