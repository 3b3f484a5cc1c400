// specula nmf (reference §7.4): non-negative matrix factorisation of every valid spectrum of the selected
// images (or a collection), out of core, with restarts, a checkpoint after every epoch and --resume.
#include <fmt/format.h>
#include <omp.h>

#include <chrono>
#include <filesystem>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/nmf/learn.h"
#include "specula/nmf/report.h"
#include "specula/store/learned_basis.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct NmfCliOptions {
  std::vector<std::string> stores;
  std::vector<std::string> images;
  std::string collection;
  std::size_t k = 0;
  std::string init = "nndsvd";
  std::uint64_t seed = 0;
  std::size_t restarts = 1;
  std::size_t max_epochs = 100;
  std::size_t wave_blocks = 8;
  double tol = 1e-4;
  std::string negatives = "clip";
  std::string name;
  std::string output;
  std::string checkpoint;
  bool resume = false;
  bool replace = false;
  bool json = false;
};

void run_nmf(const NmfCliOptions& o) {
  const std::string name = o.name.empty() ? nmf::default_basis_name(o.k) : o.name;
  store::validate_name(name, "basis");
  const std::string out = basis_output(o.stores, o.output);
  nmf::NmfOptions opt{
      .k = o.k,
      .init = nmf::parse_init(o.init),
      .seed = o.seed,
      .restarts = o.restarts,
      .max_epochs = o.max_epochs,
      .tol = o.tol,
      .negatives = nmf::parse_negatives(o.negatives),
      .wave_blocks = o.wave_blocks,
      .checkpoint = o.checkpoint.empty() ? nmf::default_checkpoint(out, name) : std::filesystem::path(o.checkpoint),
      .resume = o.resume};
  const std::vector<store::Store> stores = open_stores(o.stores);
  const store::Store& s = stores.front();
  if (!o.replace && !o.resume && store::holds_basis(out, name))  // refuse before hours of work
    throw UsageError(fmt::format("{}: basis {} already exists; choose another --name or give --replace", out, name));
  const bool root = ranks().rank() == 0;
  std::vector<nmf::EpochReport> epochs;
  opt.on_epoch = [&](const nmf::EpochReport& e) {
    epochs.push_back(e);
    if (!o.json && root)
      fmt::print("restart {} epoch {:>3}: relative error {:.6f}  ({:.1f} s)\n", e.restart + 1, e.epoch, e.rel_error,
                 e.seconds);
    std::fflush(stdout);
  };
  const auto t0 = std::chrono::steady_clock::now();
  const nmf::LearnedBasis learned = [&] {
    try {
      return nmf::learn_basis(stores, {.image_globs = o.images, .collection = o.collection}, opt, ranks());
    } catch (const Interrupted& e) {
      throw Interrupted(std::string(e.what()) + (o.checkpoint.empty() && !std::filesystem::exists(opt.checkpoint)
                                                     ? std::string()
                                                     : " (the same command with --resume)"));
    }
  }();
  if (!root) return;  // rank 0 writes and reports
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const nmf::NmfResult& r = learned.result;
  const nmf::RestartResult& best = r.best_result();
  store::save_basis(out, name, learned.basis, o.replace, command_line());
  std::error_code ec;
  std::filesystem::remove(opt.checkpoint, ec);

  if (o.json) {
    print_json(nmf::report_json(learned, {.store = s.path().string(),
                                          .basis = name,
                                          .output = out,
                                          .seconds = seconds,
                                          .epochs = epochs,
                                          .ranks = std::size_t(ranks().size())}));
    return;
  }
  fmt::print(
      "NMF of {} spectra ({}), k = {}: relative error {:.6f} (rank-{} SVD bound {:.6f}, {:+.1f} %) after {} epochs{}\n",
      r.n, learned.basis.wavelengths.describe(), o.k, r.rel_error, o.k, r.svd_bound,
      r.svd_bound > 0 ? 100 * (r.rel_error / r.svd_bound - 1) : 0.0, best.epochs,
      best.converged ? "" : " (max epochs reached)");
  if (r.restarts.size() > 1) {
    fmt::print("restart  rel error   epochs  mean/max angle to best\n");
    for (std::size_t i = 0; i < r.restarts.size(); ++i) {
      const auto& rr = r.restarts[i];
      fmt::print("{:>7}  {:.6f}  {:>6}  {:.2f}° / {:.2f}°{}\n", i + 1, rr.rel_error, rr.epochs, rr.mean_angle_deg,
                 rr.max_angle_deg, i == r.best ? "  (best)" : "");
    }
  }
  if (r.negatives)
    fmt::print("clipped {} negative values to zero ({:.4f} % of {})\n", r.negatives,
               100.0 * double(r.negatives) / double(std::max<std::uint64_t>(r.values, 1)), r.values);
  if (r.warmup_epochs)
    fmt::print("warm-up: {} epochs on a sample of {} blocks ({:.2f} passes' worth of reading)\n", r.warmup_epochs,
               r.warmup_blocks, r.warmup_pass_equivalent);
  fmt::print("{} passes over the data in {:.2f} s ({} threads); saved basis '{}' in {}\n", r.passes, seconds,
             omp_get_max_threads(), name, out);
}

}  // namespace

void setup_nmf(CLI::App& app) {
  auto o = std::make_shared<NmfCliOptions>();
  auto* cmd =
      app.add_subcommand("nmf", "Non-negative matrix factorisation of every valid spectrum, out of core (§7.4)");
  cmd->add_option("stores", o->stores, "Store file(s); several are analysed as one database")->required();
  cmd->add_option("-k", o->k, "Number of basis spectra")->required()->check(CLI::Range(1, 64));
  cmd->add_option("--images", o->images, "Image name globs (default: every image)");
  cmd->add_option("--collection", o->collection, "Use this collection instead of images");
  cmd->add_option("--init", o->init, "Initial basis: nndsvd (deterministic) or random (uniform in [0, 1])")
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of random starts (restart r uses seed + r)")->capture_default_str();
  cmd->add_option("--restarts", o->restarts, "Runs from different starts; the best is kept (restart 1 uses --init)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--max-epochs", o->max_epochs, "Passes over the data per restart at most")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--wave-blocks", o->wave_blocks,
                  "Blocks per basis update; results depend on it (not on threads or ranks): under MPI use at least "
                  "ranks x threads")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--tol", o->tol, "Stop when an epoch lowers the relative error by less than this fraction")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--negatives", o->negatives, "Values below zero: clip (to zero, counted and reported) or reject")
      ->capture_default_str();
  cmd->add_option("--name", o->name, "Name of the basis to save (default: nmf<K>)");
  cmd->add_option("-o,--output", o->output, "Store to save the basis in (default: the first input store)");
  cmd->add_option("--checkpoint", o->checkpoint, "Checkpoint file (default: <output>.nmf-<name>.checkpoint)");
  cmd->add_flag("--resume", o->resume, "Continue an interrupted run from its checkpoint");
  cmd->add_flag("--replace", o->replace, "Replace a basis of the same name");
  cmd->add_flag("--json", o->json, "Print one JSON object (k, n, rel_error, epochs, seconds, restarts, basis, ...)");
  cmd->footer(
      "Each epoch is one pass: exact NNLS coefficients for every spectrum, then the basis solved exactly from "
      "C^T C and C^T X. The error printed is ||X - CS||_F / ||X||_F, computed exactly from that pass.");
  cmd->callback([o] { run_nmf(*o); });
}

}  // namespace specula::app
