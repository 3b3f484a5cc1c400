// specula prior build: a learned BRDF prior (acquire/prior.h, docs/prior.md) from grids, into a store.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/prior.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct PriorBuildOptions {
  std::vector<std::string> grids;
  std::vector<std::string> exclude;
  std::string output;
  std::string name;
  std::size_t channels = 8;
  std::size_t components = 0;
  double epsilon = 1e-3;
  std::size_t block_mb = 256;
  bool replace = false;
};

// Each GRID argument as grid specs: a whole store (.h5 without :NAME) stands for all its grids.
std::vector<std::string> expand(const PriorBuildOptions& o) {
  std::vector<std::string> specs;
  for (const auto& g : o.grids) {
    const std::filesystem::path p(g);
    if (p.extension() == ".h5" && !store::parse_object_spec(g)) {
      for (const auto& name : store::Store::open(p).grids()) specs.push_back(g + ":" + name);
    } else {
      specs.push_back(g);
    }
  }
  std::erase_if(specs, [&](const std::string& s) {
    const auto spec = store::parse_object_spec(s);
    const std::string name = spec ? spec->name : s;
    return std::find(o.exclude.begin(), o.exclude.end(), name) != o.exclude.end() ||
           std::find(o.exclude.begin(), o.exclude.end(), s) != o.exclude.end();
  });
  if (specs.size() < 2) throw UsageError("prior build: give at least 2 training grids (after --exclude)");
  return specs;
}

// A training grid: a store's grid streams by rows; any other file is loaded whole for each block it is read in.
acquire::TrainingGrid training_grid(const std::string& spec, std::map<std::string, store::Store>& stores) {
  const auto object = store::parse_object_spec(spec);
  if (object && object->file.extension() == ".h5" && !std::filesystem::exists(spec)) {
    auto at = stores.find(object->file.string());
    if (at == stores.end()) at = stores.emplace(object->file.string(), store::Store::open(object->file)).first;
    return acquire::store_training_grid(at->second, object->name, spec);
  }
  const store::Grid first = load_grid(spec, "prior build");
  return {.name = spec,
          .wavelengths = first.wavelengths,
          .scale = first.scale,
          .read_rows = [spec](std::size_t h0, std::size_t rows, std::span<float> out) {
            const store::Grid g = load_grid(spec, "prior build");
            const std::size_t row = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;
            for (std::size_t k = 0; k < g.bands(); ++k)
              std::copy_n(g.brdf.begin() + std::ptrdiff_t(k * brdf::kMerlCells + h0 * row), rows * row,
                          out.begin() + std::ptrdiff_t(k * rows * row));
          }};
}

void run_prior_build(const PriorBuildOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  store::validate_name(o.name, "prior");
  const std::vector<std::string> specs = expand(o);
  std::vector<acquire::TrainingGrid> grids;
  std::map<std::string, store::Store> stores;
  for (const auto& spec : specs) grids.push_back(training_grid(spec, stores));
  const acquire::PriorOptions po{.channels = o.channels,
                                 .components = o.components,
                                 .epsilon = o.epsilon,
                                 .block_bytes = std::size_t(o.block_mb) << 20};
  store::StoreWriter writer(o.output, {.compression = {}, .replace = o.replace, .command_line = command_line()});
  const acquire::BrdfPrior prior = acquire::build_prior(grids, po, writer, o.name);
  writer.commit();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fmt::print(
      "prior {} of {}: {} components over {} cells, {} channels ({}), from {} grids in {:.1f} s; the retro "
      "band continued in theta_d^p, p by band width 1-{} rows: {}\n",
      o.name, o.output, prior.k(), prior.cells(), prior.channels(), prior.wavelengths.describe(), specs.size(), seconds,
      prior.retro_exponents.size(), fmt::join(prior.retro_exponents, ","));
}

}  // namespace

void setup_prior(CLI::App& app) {
  auto* prior = app.add_subcommand("prior", "Learned BRDF priors (docs/prior.md)");
  prior->require_subcommand(1);
  auto o = std::make_shared<PriorBuildOptions>();
  auto* cmd = prior->add_subcommand("build", "Learn a prior (log-relative mapping, PCA) from complete spectral grids");
  cmd->add_option("grids", o->grids, "STORE.h5:GRID, a .spgrid file, or a whole STORE.h5 (all its grids)")->required();
  cmd->add_option("-o,--output", o->output, "Store to write the prior to")->required();
  cmd->add_option("--name", o->name, "Name of the prior in the store")->required();
  cmd->add_option("--exclude", o->exclude, "Grid names to leave out (e.g. the material a capture is of)");
  cmd->add_option("--channels", o->channels, "Knots of the spectral basis the prior works in")->capture_default_str();
  cmd->add_option("--components", o->components, "Principal components kept (0: all)")->capture_default_str();
  cmd->add_option("--epsilon", o->epsilon, "eps of the log-relative mapping, 1/sr")->capture_default_str();
  cmd->add_option("--block-mb", o->block_mb,
                  "Memory for one block of cells x observations, MiB (results do not depend on it)")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 20));
  cmd->add_flag("--replace", o->replace, "Replace a prior of the same name");
  cmd->callback([o] { run_prior_build(*o); });
}

}  // namespace specula::app
