// The specula command: libraries throw, and only here do errors become one line and an exit status.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>
#include <string_view>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/version.h"

namespace {

// One line on stderr (prefixed with the rank when several processes run); then every rank stops.
int fail(int code, const std::string& message) {
  std::fprintf(stderr, "specula: %s%s\n", specula::app::rank_prefix().c_str(), message.c_str());
  std::fflush(stderr);
  specula::app::abort_ranks(code);
  return code;
}

int run(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    if (code != 0) specula::app::abort_ranks(code);
    return code;
  } catch (const specula::Interrupted& e) {
    if (std::string_view(e.what()) == "interrupted") return fail(130, "interrupted; unfinished outputs were discarded");
    return fail(130, e.what());
  } catch (const specula::Error& e) {
    return fail(1, e.what());
  } catch (const std::bad_alloc&) {
    return fail(1, "out of memory");
  } catch (const std::exception& e) {
    return fail(3, std::string("internal error: ") + e.what());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  specula::app::start_ranks(argc, argv);
  if (specula::app::ranks().rank() != 0) specula::set_progress_quiet(true);
  specula::app::set_command_line(argc, argv);
  specula::install_interrupt_handlers();
  CLI::App app{"specula " SPECULA_VERSION ": spectral images, BRDFs and learned spectral bases in HDF5 stores"};
  app.require_subcommand(1);
  app.fallthrough();
  app.set_version_flag("--version", SPECULA_VERSION);
  app.add_flag_callback(
      "-q,--quiet", [] { specula::set_progress_quiet(true); }, "No progress bars");
  specula::app::setup_import(app);
  specula::app::setup_export(app);
  specula::app::setup_relight(app);
  specula::app::setup_info(app);
  specula::app::setup_ls(app);
  specula::app::setup_synth_db(app);
  specula::app::setup_pca(app);
  specula::app::setup_project(app);
  specula::app::setup_coefficients(app);
  specula::app::setup_plot_basis(app);
  specula::app::setup_compare_bases(app);
  specula::app::setup_nmf(app);
  specula::app::setup_uplift(app);
  specula::app::setup_render(app);
  specula::app::setup_encode(app);
  specula::app::setup_resample(app);
  specula::app::setup_prior(app);
  specula::app::setup_eval_resample(app);
  specula::app::setup_synth_samples(app);
  specula::app::setup_resample_study(app);
  specula::app::setup_view(app);
  specula::app::setup_simulate_capture(app);
  specula::app::setup_acquire(app);
  specula::app::setup_filters(app);
  specula::app::setup_brdf_diff(app);
  specula::app::setup_synth_brdf(app);
  specula::app::setup_decode(app);
  specula::app::setup_rm(app);
  specula::app::setup_gc(app);
  specula::app::setup_check(app);
  specula::app::setup_upgrade(app);
  const int code = run(app, argc, argv);
  specula::app::stop_ranks();
  return code;
}
