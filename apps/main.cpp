// The specula command: libraries throw, and only here do errors become one line and an exit status.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <string_view>

#include "apps/commands.h"
#include "apps/common.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/progress.h"

int main(int argc, char** argv) {
  specula::app::set_command_line(argc, argv);
  specula::install_interrupt_handlers();
  CLI::App app{"specula " SPECULA_VERSION ": spectral images, BRDFs and learned spectral bases in HDF5 stores"};
  app.require_subcommand(1);
  app.fallthrough();
  app.set_version_flag("--version", SPECULA_VERSION);
  app.add_flag_callback("-q,--quiet", [] { specula::set_progress_quiet(true); }, "No progress bars");
  specula::app::setup_import(app);
  specula::app::setup_export(app);
  specula::app::setup_relight(app);
  specula::app::setup_info(app);
  specula::app::setup_ls(app);
  specula::app::setup_synth_db(app);
  specula::app::setup_pca(app);
  specula::app::setup_project(app);
  specula::app::setup_plot_basis(app);
  specula::app::setup_compare_bases(app);
  specula::app::setup_nmf(app);
  specula::app::setup_uplift(app);
  specula::app::setup_render(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const specula::Interrupted& e) {
    if (std::string_view(e.what()) == "interrupted")
      std::fprintf(stderr, "specula: interrupted; unfinished outputs were discarded\n");
    else
      std::fprintf(stderr, "specula: %s\n", e.what());
    return 130;
  } catch (const specula::Error& e) {
    std::fprintf(stderr, "specula: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "specula: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "specula: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
