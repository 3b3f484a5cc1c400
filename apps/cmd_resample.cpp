// specula resample (reference §5.3): a store's scattered BRDF samples onto the MERL grid through a kd-tree
// over mapped angles and Shepard-weighted (or plain) averages of the k nearest samples.
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <numbers>

#include "specula/acquire/resample.h"
#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct ResampleCliOptions {
  std::string store;
  std::string samples;
  std::string output;
  std::string mapping = "standard";
  std::size_t k = 32;
  std::string weights = "shepard";
  double power = 1;
  double max_gap_deg = 8.6;
  bool replace = false;
  bool json = false;
};

// What save_grid would refuse after the work, refused before it: an output that is neither STORE.h5:NAME, a
// .spgrid nor a .binary, a bad grid name, or a grid of that name already in the store without --replace.
void check_output(const std::string& spec, bool replace) {
  const std::filesystem::path out(spec);
  if (out.extension() == ".spgrid" || out.extension() == ".binary") return;
  const auto object = store::parse_object_spec(spec);
  if (!object || object->file.extension() != ".h5")
    throw UsageError("resample: " + spec + ": write STORE.h5:NAME, a .spgrid exchange file or an RGB .binary");
  const std::filesystem::path& file = object->file;
  const std::string& name = object->name;
  store::validate_name(name, "grid");
  if (!replace && std::filesystem::exists(file)) {
    const auto grids = store::Store::open(file).grids();
    if (std::find(grids.begin(), grids.end(), name) != grids.end())
      throw InputError(file.filename().string() + ": grid '" + name + "' exists already; choose another name or pass --replace");
  }
}

void run_resample(const ResampleCliOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(o.max_gap_deg > 0 && o.max_gap_deg <= 180)) throw UsageError("--max-gap: give degrees in (0, 180]");
  const acquire::ResampleOptions ro{.mapping = acquire::parse_mapping(o.mapping),
                                    .k = o.k,
                                    .weights = acquire::parse_weights(o.weights),
                                    .power = o.power,
                                    .max_gap = o.max_gap_deg * std::numbers::pi / 180};
  acquire::check_options(ro);
  check_output(o.output, o.replace);
  const store::Store s = store::Store::open(o.store);
  const store::SamplesInfo info = s.samples_info(o.samples);
  const acquire::StoreSamples src(s, o.samples);
  store::Grid grid;
  grid.wavelengths = info.wavelengths;
  grid.units = info.units;
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  const acquire::GridStats stats = acquire::resample_grid(src, ro, grid.brdf);
  grid.provenance.source_file = o.store + ":" + o.samples;
  grid.provenance.importer = fmt::format("resample mapping={} k={} weights={} power={} max_gap_deg={}", o.mapping, o.k,
                                         o.weights, o.power, o.max_gap_deg);
  const std::string what = save_grid(grid, o.output, o.replace, "resample");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j;
    j["samples"] = info.size;
    j["bands"] = info.bands;
    j["cells"] = brdf::kMerlCells;
    j["valid_cells"] = stats.valid_cells;
    j["seconds"] = seconds;
    j["tree_seconds"] = stats.tree_seconds;
    j["query_seconds"] = stats.query_seconds;
    j["average_seconds"] = stats.average_seconds;
    j["passes"] = stats.passes;
    j["mapping"] = o.mapping;
    j["k"] = o.k;
    j["weights"] = o.weights;
    j["power"] = o.power;
    j["output"] = o.output;
    j["threads"] = omp_get_max_threads();
    print_json(j);
    return;
  }
  fmt::print("resampled {} samples of {} onto {} of {} cells ({} mapping, k = {}, {} weights) in {:.2f} s: {}\n", info.size,
             o.samples, stats.valid_cells, brdf::kMerlCells, o.mapping, o.k, o.weights, seconds, what);
}

}  // namespace

void setup_resample(CLI::App& app) {
  auto o = std::make_shared<ResampleCliOptions>();
  auto* cmd = app.add_subcommand("resample", "Scattered BRDF samples onto the MERL grid (kd-tree, k nearest, Shepard)");
  cmd->add_option("store", o->store, "Store holding the samples")->required();
  cmd->add_option("samples", o->samples, "Name of the scattered samples in the store")->required();
  cmd->add_option("-o,--output", o->output, "STORE.h5:GRID, a .spgrid file, or an RGB .binary")->required();
  cmd->add_option("--mapping", o->mapping, "standard (M_s), marschner (M_m, eq 5.8) or halfdiff (M_h)")->capture_default_str();
  cmd->add_option("-k", o->k, "Nearest samples per cell")->capture_default_str();
  cmd->add_option("--weights", o->weights, "shepard (eqs 5.9-5.10) or mean")->capture_default_str();
  cmd->add_option("--power", o->power, "Shepard's power p")->capture_default_str();
  cmd->add_option("--max-gap", o->max_gap_deg,
                  "Leave a cell without data when its nearest sample is farther than this (degrees in theta_i, theta_o, phi_d)")
      ->capture_default_str();
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->add_flag("--json", o->json, "Print one JSON object (samples, cells, valid_cells, seconds)");
  cmd->callback([o] { run_resample(*o); });
}

}  // namespace specula::app
