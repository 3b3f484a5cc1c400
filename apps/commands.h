#pragma once
// Every subcommand lives in its own file with an options struct, a setup function that registers it
// (its callback runs it) and a run function.
#include <CLI/CLI.hpp>

namespace specula::app {

void setup_import(CLI::App& app);
void setup_export(CLI::App& app);
void setup_relight(CLI::App& app);
void setup_info(CLI::App& app);
void setup_ls(CLI::App& app);
void setup_synth_db(CLI::App& app);
void setup_pca(CLI::App& app);
void setup_project(CLI::App& app);
void setup_coefficients(CLI::App& app);
void setup_plot_basis(CLI::App& app);
void setup_compare_bases(CLI::App& app);
void setup_nmf(CLI::App& app);
void setup_uplift(CLI::App& app);
void setup_render(CLI::App& app);
void setup_encode(CLI::App& app);
void setup_resample(CLI::App& app);
void setup_prior(CLI::App& app);
void setup_eval_resample(CLI::App& app);
void setup_synth_samples(CLI::App& app);
void setup_resample_study(CLI::App& app);
void setup_view(CLI::App& app);
void setup_simulate_capture(CLI::App& app);
void setup_acquire(CLI::App& app);
void setup_brdf_diff(CLI::App& app);
void setup_synth_brdf(CLI::App& app);
void setup_decode(CLI::App& app);
void setup_rm(CLI::App& app);
void setup_gc(CLI::App& app);
void setup_check(CLI::App& app);
void setup_upgrade(CLI::App& app);
void setup_filters(CLI::App& app);

}  // namespace specula::app
