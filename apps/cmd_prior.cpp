// specula prior build: a learned BRDF prior (acquire/prior.h, docs/prior.md) from grids, into a store.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/prior.h"
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

void run_prior_build(const PriorBuildOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  store::validate_name(o.name, "prior");
  const std::vector<acquire::TrainingSource> sources(o.grids.begin(), o.grids.end());
  const std::vector<acquire::TrainingGrid> grids = acquire::training_grids(
      sources, o.exclude,
      [](const std::string& spec) {
        return acquire::reloaded_training_grid(spec, [spec] { return load_grid(spec, "prior build"); });
      },
      "prior build", "--exclude");
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
      o.name, o.output, prior.k(), prior.cells(), prior.channels(), prior.wavelengths.describe(), grids.size(), seconds,
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
