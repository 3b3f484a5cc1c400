// specula resample (reference §5.3): a store's scattered BRDF samples onto the MERL grid through a kd-tree
// over mapped angles and Shepard-weighted (or plain) averages of the k nearest samples.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <numbers>
#include <optional>
#include <vector>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/prior_output.h"
#include "specula/acquire/resample_run.h"
#include "specula/codec/grid_files.h"
#include "specula/core/brdf_geometry.h"
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
  std::string k = "32";  // a count, or "auto": chosen by leave-one-out (acquire/bandwidth.h)
  std::string k_criterion = "bands";
  std::size_t k_held_out = 2000;
  std::string weights = "shepard";
  double power = 1;
  double max_gap_deg = brdf::kDefaultMaxGapDegrees;
  bool replace = false;
  bool json = false;
  std::string prior;  // STORE.h5:PRIOR
  double lambda = 1e-3;
  std::optional<std::string> confidence_reach;  // a fraction, or "auto"; the library's default when not given
  std::string model;                            // ggx | beckmann
  std::size_t lobes = 1;
  std::string fresnel = "schlick";
  std::string shadowing = "smith";
  bool prior_residuals = false;
  bool kd_tree_in_cap = false;
  bool blend_in_retro = false;
  bool no_ceiling = false;
  bool no_energy_bound = false;
  bool prior_alone_in_cap = false;
  bool linear_blend = false;
  bool no_log_residuals = false;
  bool log_residuals_in_retro = false;
  bool no_log_residuals_in_retro = false;
  bool no_retro_pole = false;
  bool retro_rise = false;
  std::string peak_rows = "auto";
  acquire::LogResidualOptions log_residuals;
  bool no_retro_continuation = false;
  bool retro_weight_overall = false;
  std::string prior_weights = "noise";
  std::size_t prior_block_mb = 256;
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
      throw InputError(file.filename().string() + ": grid '" + name +
                       "' exists already; choose another name or pass --replace");
  }
}

// The confidence grid beside `output`: STORE.h5:NAME.confidence, or X.confidence.spgrid beside X.spgrid.
std::string confidence_output(const std::string& output) {
  const std::filesystem::path p(output);
  if (p.extension() == ".spgrid") return acquire::confidence_path(p).string();
  if (p.extension() == ".binary")
    throw UsageError("resample --prior/--model: write STORE.h5:NAME or a .spgrid (the confidence goes beside it)");
  return output + ".confidence";
}

// The grid and its confidence, both or neither: one store transaction, or two exchange files renamed into place
// only when both are written.
std::string save_prior_grids(const store::Grid& grid, const store::Grid& conf, const std::string& output,
                             const std::string& conf_out, bool replace) {
  if (std::filesystem::path(output).extension() == ".spgrid") {
    const std::pair<std::filesystem::path, const store::Grid*> files[] = {{output, &grid}, {conf_out, &conf}};
    codec::write_grid_files(files);
    return "spectral grid file " + output;
  }
  const auto spec = store::parse_object_spec(output);
  store::StoreWriter w(spec->file, {.compression = {}, .replace = replace, .command_line = command_line()});
  acquire::add_prior_grids(w, spec->name, grid, conf);
  w.commit();
  return "grid '" + spec->name + "' in " + spec->file.string();
}

// --confidence-reach as a number (the library checks its range).
double reach_of(const std::string& text) {
  std::size_t used = 0;
  double r = 0;
  try {
    r = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size())
    throw UsageError("--confidence-reach: give a fraction of --max-gap in (0, 1] or 'auto', got '" + text + "'");
  return r;
}

// --peak-rows: a count of theta_h rows in [0, 90), or 'auto'.
int peak_rows_of(const std::string& text) {
  std::size_t used = 0;
  int rows = -1;
  try {
    rows = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || rows < 0 || rows >= brdf::kMerlThetaH)
    throw UsageError("--peak-rows: give a count of theta_h rows in [0, 90) or 'auto', got '" + text + "'");
  return rows;
}

// The job the options describe; UsageError naming the flag for what only the command line can get wrong.
acquire::ResampleJob job_of(const ResampleCliOptions& o) {
  if (o.k_held_out < 1) throw UsageError("--k-held-out: give at least 1");
  if (!o.prior.empty() && !o.model.empty()) throw UsageError("resample: give --prior or --model, not both");
  acquire::ResampleJob job{.store = o.store,
                           .samples = o.samples,
                           .local = {.mapping = brdf::parse_mapping(o.mapping),
                                     .weights = brdf::parse_weights(o.weights),
                                     .power = o.power,
                                     .max_gap = o.max_gap_deg * std::numbers::pi / 180}};
  const auto criterion = acquire::parse_bandwidth_criterion(o.k_criterion);
  if (o.k == "auto") {
    job.k_auto = acquire::BandwidthOptions{.held_out = o.k_held_out, .criterion = criterion};
  } else if (o.k == "holdout") {
    if (o.prior.empty()) throw UsageError("-k holdout: chosen by the prior's holdout, only with --prior");
  } else {
    std::size_t used = 0;
    try {
      job.local.k = std::stoul(o.k, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != o.k.size())
      throw UsageError("-k: give a count of neighbours, 'auto' or (with --prior) 'holdout', got '" + o.k + "'");
  }
  if (!o.prior.empty()) {
    acquire::PriorMethod m{.prior = o.prior,
                           .fit = {.lambda = o.lambda,
                                   .weights = acquire::parse_prior_weights(o.prior_weights),
                                   .block_bytes = o.prior_block_mb << 20},
                           .residuals = o.prior_residuals,
                           .prior_in_cap = !o.kd_tree_in_cap,
                           .ceiling = !o.no_ceiling,
                           .log_blend = !o.linear_blend};
    if (o.confidence_reach == "auto" && o.prior_residuals)
      throw UsageError("--confidence-reach auto: chosen for the blend, not with --prior-residuals");
    if (o.confidence_reach ? *o.confidence_reach != "auto" : o.prior_residuals) m.reach_auto.reset();
    if (o.confidence_reach && *o.confidence_reach != "auto") m.confidence_reach = reach_of(*o.confidence_reach);
    if (o.k == "holdout" && !m.reach_auto)
      throw UsageError(
          "-k holdout: chosen with the reach, so not with a --confidence-reach given or --prior-residuals");
    if (o.k == "holdout") m.reach_auto->k_ladder = acquire::kReachKLadder;
    if (o.blend_in_retro && m.reach_auto) m.reach_auto->retro_ladder.clear();
    if (o.no_retro_continuation && m.reach_auto) m.reach_auto->retro_continued = false;
    if (o.retro_weight_overall && m.reach_auto) m.reach_auto->retro_by_group = false;
    if (o.prior_alone_in_cap) m.cap_auto.reset();
    if (o.no_energy_bound) m.energy_bound.reset();
    m.log_residuals = o.log_residuals;
    m.log_residuals->into_retro_band = o.log_residuals_in_retro;
    m.retro_residuals_auto = !o.log_residuals_in_retro && !o.no_log_residuals_in_retro;
    if (o.no_log_residuals) m.log_residuals.reset();
    m.retro_pole = !o.no_retro_pole;
    m.retro_rise = o.retro_rise;
    if (o.peak_rows != "auto") {
      m.peak_auto.reset();
      m.peak_rows = peak_rows_of(o.peak_rows);
    }
    job.method = m;
  } else if (!o.model.empty()) {
    acquire::ModelMethod m{.fit = {.kind = {.distribution = acquire::parse_distribution(o.model),
                                            .shadowing = acquire::parse_shadowing(o.shadowing),
                                            .fresnel = acquire::parse_fresnel(o.fresnel)},
                                   .lobes = o.lobes}};
    if (o.confidence_reach == "auto") throw UsageError("--confidence-reach auto: only with --prior");
    if (o.confidence_reach) m.confidence_reach = reach_of(*o.confidence_reach);
    job.method = m;
  }
  acquire::check_job(job);
  return job;
}

void run_resample(const ResampleCliOptions& o) {
  const acquire::ResampleJob job = job_of(o);
  const bool with_confidence = !std::holds_alternative<acquire::PlainMethod>(job.method);
  const std::string conf_out = with_confidence ? confidence_output(o.output) : "";
  check_output(o.output, o.replace);
  if (with_confidence) check_output(conf_out, o.replace);
  acquire::ResampleOutcome r = acquire::run_resample(job);
  std::string what;
  if (r.confidence) {
    r.confidence->provenance.importer = "resample confidence of " + o.output;
    what = save_prior_grids(r.grid, *r.confidence, o.output, conf_out, o.replace);
  } else {
    what = save_grid(r.grid, o.output, o.replace, "resample");
  }
  if (o.json) {
    r.report["output"] = o.output;
    if (r.confidence) r.report["confidence"] = conf_out;
    return print_json(r.report);
  }
  fmt::print("{}: {}{}\n", r.summary, what, r.confidence ? "; confidence in " + conf_out : "");
}

}  // namespace

void setup_resample(CLI::App& app) {
  auto o = std::make_shared<ResampleCliOptions>();
  auto* cmd = app.add_subcommand("resample", "Scattered BRDF samples onto the MERL grid (kd-tree, k nearest, Shepard)");
  cmd->add_option("store", o->store, "Store holding the samples")->required();
  cmd->add_option("samples", o->samples, "Name of the scattered samples in the store")->required();
  cmd->add_option("-o,--output", o->output, "STORE.h5:GRID, a .spgrid file, or an RGB .binary")->required();
  cmd->add_option("--mapping", o->mapping, "standard (M_s), marschner (M_m, eq 5.8) or halfdiff (M_h)")
      ->capture_default_str();
  cmd->add_option("-k", o->k,
                  "Nearest samples per cell, or auto: the k of a fixed ladder (4 to 128) predicting held-out samples "
                  "best by leave-one-out (docs/resampling.md), or (--prior) holdout: the k of 8, 16, 32 or 64 whose "
                  "blend the prior's holdout finds closest, chosen with the reach (docs/prior.md)")
      ->capture_default_str();
  auto* k_criterion =
      cmd->add_option(
             "--k-criterion", o->k_criterion,
             "-k auto: bands (the mean over theta_h bands of each band's median relative error of the held-out "
             "spectra), median (their median relative error) or rms (their relative RMS)")
          ->capture_default_str();
  auto* k_held_out =
      cmd->add_option("--k-held-out", o->k_held_out, "-k auto: samples left out one at a time (fixed seed)")
          ->capture_default_str();
  cmd->add_option("--weights", o->weights,
                  "loess (local linear fit, Wendland-weighted; smoothing), wendland (kernel (1 - d/R)^4 (4 d/R + 1); "
                  "smoothing), renka (Franke-Little: ((R - d)+ / (R d))^2; continuous), shepard (eqs 5.9-5.10, the "
                  "reference's) or mean; R the (k+1)-th nearest sample's distance")
      ->capture_default_str();
  cmd->add_option("--power", o->power, "Shepard's power p (--weights shepard only)")->capture_default_str();
  cmd->add_option(
         "--max-gap", o->max_gap_deg,
         "Leave a cell without data when its nearest sample is farther than this (degrees in theta_i, theta_o, phi_d)")
      ->capture_default_str();
  cmd->add_option(
      "--prior", o->prior,
      "STORE.h5:PRIOR: fit a learned prior (specula prior build) and fill every valid cell, blending with "
      "the kd-tree estimate by per-cell confidence, written beside the grid as NAME.confidence (docs/prior.md)");
  cmd->add_option("--model", o->model,
                  "ggx or beckmann: fit a Lambertian plus microfacet lobes with spectral albedos as the base, add the "
                  "kd-tree estimate of the residuals near samples, fill every valid cell (confidence beside the grid)");
  cmd->add_option("--lobes", o->lobes, "--model: 1 or 2 microfacet lobes")->capture_default_str();
  cmd->add_option("--fresnel", o->fresnel, "--model: schlick (fitted F0) or dielectric (fitted eta)")
      ->capture_default_str();
  cmd->add_option("--shadowing", o->shadowing, "--model: smith (height-correlated) or vgroove (Torrance-Sparrow)")
      ->capture_default_str();
  cmd->add_option("--lambda", o->lambda, "--prior: Tikhonov weight of the fit")->capture_default_str();
  cmd->add_option("--prior-weights", o->prior_weights,
                  "--prior: a cell's weight in the fit: noise (the samples' own variance when they carry one, else "
                  "their scatter), scatter, or count")
      ->capture_default_str();
  cmd->add_option("--prior-block-mb", o->prior_block_mb,
                  "--prior: memory for one block of the prior's components the fit reads at a time, MiB (results do "
                  "not depend on it)")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 20));
  cmd->add_option(
      "--confidence-reach", o->confidence_reach,
      fmt::format(
          "--prior, --model: the kd-tree estimate's weight falls from 1 at a sample to 0 at this fraction "
          "of --max-gap, or (--prior) auto: chosen per group of theta_h rows by holding out half the samples of a "
          "tenth of the observed cells, with the weight in the unseen retro-reflection band (docs/prior.md). Default "
          "auto with --prior ({} with --prior-residuals), {} with --model",
          acquire::kPriorConfidenceReach, acquire::ModelMethod{}.confidence_reach));
  cmd->add_flag("--prior-residuals", o->prior_residuals,
                "--prior: add the kd-tree estimate of the residuals against the prior fit (as --model) instead of "
                "blending the two");
  cmd->add_flag(
      "--kd-tree-in-cap", o->kd_tree_in_cap,
      "--prior: keep the kd-tree estimate in the theta_h rows below the lowest sampled one (the unseen cap "
      "round the specular peak), blended by confidence as elsewhere, instead of the prior with the kd-tree's weight "
      "chosen there (docs/prior.md)");
  cmd->add_flag("--blend-in-retro", o->blend_in_retro,
                "--prior: blend the prior and the kd-tree estimate by confidence in the theta_d rows below the lowest "
                "sampled one (the unseen band round retro-reflection) as elsewhere, instead of the kd-tree weight "
                "chosen there with --confidence-reach auto (docs/prior.md)");
  cmd->add_flag("--prior-alone-in-cap", o->prior_alone_in_cap,
                "--prior: the prior alone in the unseen cap round the specular peak, instead of the kd-tree's weight "
                "there chosen by rehearsing the cap one cap higher (docs/prior.md)");
  cmd->add_flag("--no-retro-continuation", o->no_retro_continuation,
                "--prior: in the unseen retro band, weigh only the kd-tree's estimate against the prior, not also the "
                "material's trend continued down in theta_d (docs/prior.md)");
  cmd->add_flag("--retro-weight-overall", o->retro_weight_overall,
                "--prior: one kd-tree weight for the whole unseen retro band, instead of one per theta_h group chosen "
                "from that group's rehearsal cells (docs/prior.md)");
  cmd->add_flag("--linear-blend", o->linear_blend,
                "--prior: mix the kd-tree estimate and the prior linearly with the weights chosen for the unseen cap "
                "and retro band, instead of in the log domain the choice judges them in (docs/prior.md)");
  cmd->add_flag("--no-ceiling", o->no_ceiling,
                "--prior: leave the fit unbounded in the unseen cap, instead of no higher than any training material "
                "at each cell (the prior's ceiling; docs/prior.md)");
  cmd->add_flag("--no-energy-bound", o->no_energy_bound,
                "--prior: leave the fit's directional albedo unbounded, instead of at most max(2, 2 x the material's "
                "median albedo) at every incidence, which cuts a runaway fit (docs/prior.md)");
  cmd->add_flag("--no-log-residuals", o->no_log_residuals,
                "--prior: leave the blend as it is, instead of correcting each cell near samples by the mean of their "
                "log residuals against it over the cells around it (docs/prior.md)");
  cmd->add_option("--log-residual-radius", o->log_residuals.radius,
                  "--prior: the log residuals are averaged over the cells within this many on each index axis")
      ->capture_default_str()
      ->check(CLI::Range(0, 10));
  auto* in_retro = cmd->add_flag("--log-residuals-in-retro", o->log_residuals_in_retro,
                                 "--prior: always carry the log residuals' mean at the lowest theta_d row the boxes "
                                 "reach down into the unseen retro band, instead of as the rehearsal one band higher "
                                 "chooses (docs/prior.md)");
  cmd->add_flag("--no-log-residuals-in-retro", o->no_log_residuals_in_retro,
                "--prior: never carry the log residuals into the unseen retro band, instead of as the rehearsal one "
                "band higher chooses (docs/prior.md)")
      ->excludes(in_retro);
  cmd->add_option("--log-residual-passes", o->log_residuals.passes,
                  "--prior: corrections by the log residuals in turn, each against the grid the one before left")
      ->capture_default_str()
      ->check(CLI::Range(1, 10));
  cmd->add_flag("--no-retro-pole", o->no_retro_pole,
                "--prior: leave the unseen retro band's dependence on phi_d as the estimates made it, instead of "
                "fading it towards theta_d = 0 as sin^2 theta_d, where every phi_d is the same pair of directions "
                "(docs/prior.md)");
  cmd->add_flag("--retro-rise", o->retro_rise,
                "--prior: scale the unseen retro band's rows from theta_h = 22.5 degrees on to the rise the prior "
                "learned from its training materials' shoulders, as the result's own shoulder predicts it (a prior "
                "built by this version; docs/prior.md)");
  cmd->add_option(
         "--peak-rows", o->peak_rows,
         "--prior: fade the dependence on phi_d of the theta_h rows below this round the specular peak "
         "towards theta_h = 0 as sin^2 theta_h, each ring's level from the samples anywhere on it, as an "
         "isotropic BRDF asks; 'auto' judges them in groups of 5 rows, each keeping the share of its spread over "
         "phi_d that the samples' own spread accounts for, 0 none (docs/prior.md)")
      ->capture_default_str();
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->add_flag("--json", o->json, "Print one JSON object (samples, cells, valid_cells, seconds)");
  std::vector<const CLI::Option*> prior_only, model_only;
  for (const char* name : {"--lambda",
                           "--prior-weights",
                           "--prior-block-mb",
                           "--prior-residuals",
                           "--kd-tree-in-cap",
                           "--blend-in-retro",
                           "--prior-alone-in-cap",
                           "--no-retro-continuation",
                           "--retro-weight-overall",
                           "--linear-blend",
                           "--no-ceiling",
                           "--no-energy-bound",
                           "--no-log-residuals",
                           "--log-residual-radius",
                           "--log-residuals-in-retro",
                           "--no-log-residuals-in-retro",
                           "--log-residual-passes",
                           "--no-retro-pole",
                           "--retro-rise",
                           "--peak-rows"})
    prior_only.push_back(cmd->get_option(name));
  for (const char* name : {"--lobes", "--fresnel", "--shadowing"}) model_only.push_back(cmd->get_option(name));
  const CLI::Option* reach = cmd->get_option("--confidence-reach");
  cmd->callback([o, k_criterion, k_held_out, prior_only, model_only, reach] {
    if ((k_criterion->count() > 0 || k_held_out->count() > 0) && o->k != "auto")
      throw UsageError("--k-criterion, --k-held-out: only with -k auto");
    for (const CLI::Option* opt : prior_only)
      if (opt->count() > 0 && o->prior.empty()) throw UsageError(opt->get_name() + ": only with --prior");
    for (const CLI::Option* opt : model_only)
      if (opt->count() > 0 && o->model.empty()) throw UsageError(opt->get_name() + ": only with --model");
    if (reach->count() > 0 && o->prior.empty() && o->model.empty())
      throw UsageError("--confidence-reach: only with --prior or --model");
    run_resample(*o);
  });
}

}  // namespace specula::app
