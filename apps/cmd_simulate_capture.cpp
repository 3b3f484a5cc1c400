// specula simulate-capture: a capture directory of the reference's rig (acquire/simulate.h) with known truth:
// scene exposures per light and band, silhouette, mirror sphere, flat fields and diffuse targets, as 16-bit PNGs
// and manifest.json (docs/capture-format.md). Real captures in the same layout go through `specula acquire`.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/filters.h"
#include "specula/acquire/simulate.h"
#include "specula/core/atomic_file.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"
#include "specula/core/wavelengths.h"
#include "specula/store/io/csv.h"
#include "specula/store/object_spec.h"

namespace specula::app {
namespace {

struct SimulateCaptureOptions {
  acquire::SimulatorOptions sim;
  std::string output;
  std::string size = "256x256";
  std::string bands = "420:720:10";
  std::string passband = "gaussian";
  std::string filters;
  std::string holdout;
  bool no_noise = false;
  bool json = false;
};

void run_simulate_capture(SimulateCaptureOptions o) {
  const auto t0 = std::chrono::steady_clock::now();
  int w = 0, h = 0;
  if (std::sscanf(o.size.c_str(), "%dx%d", &w, &h) != 2)
    throw UsageError("simulate-capture: --size is WIDTHxHEIGHT, e.g. 256x256");
  o.sim.width = w;
  o.sim.height = h;
  const WavelengthGrid bands = WavelengthGrid::parse(o.bands);
  o.sim.bands.assign(bands.values().begin(), bands.values().end());
  if (o.passband != "gaussian" && o.passband != "delta")
    throw UsageError("simulate-capture: --passband is gaussian or delta");
  o.sim.passband = o.passband == "delta" ? acquire::Passband::delta : acquire::Passband::gaussian;
  if (!o.filters.empty()) {
    o.sim.filters = acquire::read_filters_csv(o.filters);
    acquire::check_filters(*o.sim.filters, o.sim.bands, o.filters);
  }
  if (!o.holdout.empty()) o.sim.holdout = store::read_csv_collection(o.holdout);
  o.sim.noise = !o.no_noise;
  // The sphere sits a little off the optical axis (5 % and 2 % of its image diameter), as on the real rig.
  o.sim.rig.off_axis = 0.05 * o.sim.rig.sphere_px / o.sim.rig.focal_px * o.sim.rig.distance;
  o.sim.rig.off_axis_y = 0.02 * o.sim.rig.sphere_px / o.sim.rig.focal_px * o.sim.rig.distance;
  // A store grid (STORE.h5:GRID), a .spgrid or an RGB MERL .binary (uplifted) instead of a named material.
  if (!brdf::material_catalogue().count(o.sim.material) &&
      (store::parse_object_spec(o.sim.material) || o.sim.material.ends_with(".spgrid") ||
       o.sim.material.ends_with(".binary")))
    o.sim.grid = std::make_shared<const store::Grid>(load_grid(o.sim.material, "simulate-capture"));
  acquire::check_simulator(o.sim);
  // Written under a temporary name and renamed, so an interrupted run leaves no half capture behind.
  const std::filesystem::path out(o.output);
  if (std::filesystem::exists(out)) throw UsageError("simulate-capture: " + o.output + " exists; name a new directory");
  const std::filesystem::path temp = out.string() + ".partial";
  std::filesystem::remove_all(temp);
  const acquire::Capture c = acquire::simulate_capture(o.sim, temp);
  std::filesystem::rename(temp, out);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j;
    j["output"] = o.output;
    j["images"] = c.images.size();
    j["width"] = c.width;
    j["height"] = c.height;
    j["lights"] = c.light_angles_deg.size();
    j["bands"] = c.bands.size();
    j["channels"] = c.channels();
    std::size_t scene = 0;
    double exposure = 0;
    for (const auto& im : c.images)
      if (im.kind == acquire::ImageKind::scene) ++scene, exposure += im.exposure_s;
    j["scene_images"] = scene;
    j["scene_exposure_s"] = exposure;
    j["holdout_patches"] = c.holdout.size();
    j["seconds"] = seconds;
    print_json(j);
    return;
  }
  fmt::print("wrote {} images ({}) into {} in {:.1f} s\n", c.images.size(), c.description, o.output, seconds);
}

}  // namespace

void setup_simulate_capture(CLI::App& app) {
  auto o = std::make_shared<SimulateCaptureOptions>();
  auto* cmd =
      app.add_subcommand("simulate-capture", "Simulate a capture of the reference's BRDF rig, with known truth");
  cmd->add_option("--material", o->sim.material,
                  "The sphere's material: a name (see synth-brdf), STORE.h5:GRID, .spgrid or .binary")
      ->capture_default_str();
  cmd->add_option("-o,--output", o->output, "New capture directory")->required();
  cmd->add_option("--size", o->size, "Sensor WIDTHxHEIGHT (pixels)")->capture_default_str();
  cmd->add_option("--sphere-px", o->sim.rig.sphere_px, "The sphere's diameter on the image (pixels)")
      ->capture_default_str();
  cmd->add_option("--focal", o->sim.rig.focal_px, "Focal length (pixels)")->capture_default_str();
  cmd->add_option("--lights", o->sim.rig.lights, "Light positions on the arc")->capture_default_str();
  cmd->add_option("--light-step", o->sim.rig.light_step_deg, "Arc step (degrees)")->capture_default_str();
  cmd->add_option("--first-light", o->sim.rig.first_light_deg, "First light's angle from the camera (degrees)")
      ->capture_default_str();
  cmd->add_option("--bands", o->bands, "LCTF tuning wavelengths (first:last:step or a list, nm)")
      ->capture_default_str();
  cmd->add_option("--exposures", o->sim.exposures_s, "Exposure times (seconds)")->delimiter(',')->capture_default_str();
  cmd->add_option("--passband", o->passband, "LCTF passband model: gaussian (widening to the red) or delta")
      ->capture_default_str();
  cmd->add_option("--filters", o->filters,
                  "Filter CSV (specula filters design): a filter wheel instead of the LCTF, exposures per filter");
  cmd->add_option("--holdout-targets", o->holdout,
                  "Reflectance table (CSV, as specula import reads) imaged as a chart of held-out patches that "
                  "acquire run recovers and never calibrates on");
  cmd->add_option("--lctf-peak", o->sim.lctf_peak,
                  "The LCTF's peak transmission (filter captures are exposed "
                  "relative to it)")
      ->capture_default_str();
  cmd->add_option("--brightness", o->sim.brightness, "DN/s of a white Lambertian facing light and camera")
      ->capture_default_str();
  cmd->add_option("--light-kelvin", o->sim.light_kelvin, "The light's colour temperature (a blackbody)")
      ->capture_default_str();
  cmd->add_option("--fwhm", o->sim.fwhm_blue_nm, "Passband FWHM at 420 nm (nm)")->capture_default_str();
  cmd->add_option("--fwhm-red", o->sim.fwhm_red_nm, "Passband FWHM at 720 nm (nm)")->capture_default_str();
  cmd->add_option("--read-noise", o->sim.read_noise_dn, "Read noise (DN)")->capture_default_str();
  cmd->add_option("--vignetting", o->sim.vignetting, "Fraction of light lost at the image corner")
      ->capture_default_str();
  cmd->add_option("--seed", o->sim.seed, "Noise seed")->capture_default_str();
  cmd->add_flag("--no-noise", o->no_noise, "Noise-free sensor (still quantised to 12 bits and clipped)");
  cmd->add_flag("--json", o->json, "Print one JSON object");
  cmd->callback([o] { run_simulate_capture(*o); });
}

}  // namespace specula::app
