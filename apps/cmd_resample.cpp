// specula resample (reference §5.3): a store's scattered BRDF samples onto the MERL grid through a kd-tree
// over mapped angles and Shepard-weighted (or plain) averages of the k nearest samples.
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <numbers>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/bandwidth.h"
#include "specula/acquire/base_resample.h"
#include "specula/acquire/prior_output.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/resample.h"
#include "specula/codec/grid_files.h"
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
  double max_gap_deg = 8.6;
  bool replace = false;
  bool json = false;
  std::string prior;  // STORE.h5:PRIOR
  double lambda = 1e-3;
  double confidence_reach = 1;
  std::string model;  // ggx | beckmann
  std::size_t lobes = 1;
  std::string fresnel = "schlick";
  std::string shadowing = "smith";
  bool prior_residuals = false;
  bool kd_tree_in_cap = false;
  std::string prior_weights = "noise";
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

// A grid on the samples' bands and units, every value zero, for a resampler to fill.
store::Grid empty_grid(const store::SamplesInfo& info) {
  store::Grid grid;
  grid.wavelengths = info.wavelengths;
  grid.units = info.units;
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  return grid;
}

// What both kinds of resampling report first: the samples read and the grid's cells.
Json report_head(const store::SamplesInfo& info, std::uint64_t valid_cells) {
  return {{"samples", info.size}, {"bands", info.bands}, {"cells", brdf::kMerlCells}, {"valid_cells", valid_cells}};
}

// --prior: the prior fitted to the samples' cell means, blended with the kd-tree estimate by per-cell confidence.
void run_prior_resample(const ResampleCliOptions& o, const acquire::ResampleOptions& ro) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto prior_spec = store::parse_object_spec(o.prior);
  if (!prior_spec) throw UsageError("resample --prior: give STORE.h5:PRIOR");
  const std::string conf_out = confidence_output(o.output);
  check_output(conf_out, o.replace);
  const acquire::BrdfPrior prior = acquire::read_prior(store::Store::open(prior_spec->file), prior_spec->name);
  const store::Store s = store::Store::open(o.store);
  const store::SamplesInfo info = s.samples_info(o.samples);
  const acquire::StoreSamples src(s, o.samples);
  store::Grid grid = empty_grid(info);
  std::vector<float> confidence(brdf::kMerlCells);
  const acquire::PriorResampleOptions po{
      .local = ro,
      .fit = {.lambda = o.lambda, .weights = acquire::parse_prior_weights(o.prior_weights)},
      .confidence_reach = o.confidence_reach,
      .residuals = o.prior_residuals,
      .prior_in_cap = !o.kd_tree_in_cap};
  const acquire::PriorResampleStats st = acquire::resample_with_prior(src, prior, po, grid.brdf, confidence);
  store::Grid conf = acquire::confidence_grid(confidence, info.wavelengths);
  grid.provenance.source_file = conf.provenance.source_file = o.store + ":" + o.samples;
  grid.provenance.importer = fmt::format(
      "resample prior={} lambda={} prior_weights={} confidence_reach={} prior_in_cap={} mapping={} k={} "
      "weights={}",
      o.prior, o.lambda, o.prior_weights, o.confidence_reach, !o.kd_tree_in_cap, o.mapping, o.k, o.weights);
  conf.provenance.importer = "resample confidence of " + o.output;
  const std::string what = save_prior_grids(grid, conf, o.output, conf_out, o.replace);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j = report_head(info, st.filled_cells);
    j["observed_cells"] = st.observed_cells;
    j["seconds"] = seconds;
    j["fit_seconds"] = st.fit_seconds;
    j["prior"] = o.prior;
    j["output"] = o.output;
    j["confidence"] = conf_out;
    j["threads"] = omp_get_max_threads();
    print_json(j);
    return;
  }
  fmt::print(
      "resampled {} samples of {} with prior {} onto all {} valid cells ({} observed) in {:.2f} s: {}; "
      "confidence in {}\n",
      info.size, o.samples, o.prior, st.filled_cells, st.observed_cells, seconds, what, conf_out);
}

// The fitted model as JSON: its kind, each lobe's shape, and the albedos per band.
Json model_json(const acquire::MicrofacetBrdf& m) {
  Json lobes = Json::array();
  for (std::size_t j = 0; j < m.shapes().size(); ++j) {
    const Eigen::VectorXd& s = m.specular()[j];
    lobes.push_back({{"alpha", m.shapes()[j].alpha},
                     {m.kind().fresnel == acquire::FresnelKind::schlick ? "f0" : "eta", m.shapes()[j].fresnel},
                     {"albedo", std::vector<double>(s.begin(), s.end())}});
  }
  return {{"distribution", acquire::distribution_name(m.kind().distribution)},
          {"shadowing", acquire::shadowing_name(m.kind().shadowing)},
          {"fresnel", acquire::fresnel_name(m.kind().fresnel)},
          {"diffuse", std::vector<double>(m.diffuse().begin(), m.diffuse().end())},
          {"lobes", lobes}};
}

// --model: a Lambertian plus microfacet lobes fitted to the samples as the base, the kd-tree estimate of the
// residuals added where samples are near (by per-cell confidence, written beside the grid).
void run_model_resample(const ResampleCliOptions& o, const acquire::ResampleOptions& ro) {
  const auto t0 = std::chrono::steady_clock::now();
  const acquire::ModelFitOptions fo{.kind = {.distribution = acquire::parse_distribution(o.model),
                                             .shadowing = acquire::parse_shadowing(o.shadowing),
                                             .fresnel = acquire::parse_fresnel(o.fresnel)},
                                    .lobes = o.lobes};
  if (o.lobes < 1 || o.lobes > 2) throw UsageError("--lobes: give 1 or 2");
  const std::string conf_out = confidence_output(o.output);
  check_output(conf_out, o.replace);
  const store::Store s = store::Store::open(o.store);
  const store::SamplesInfo info = s.samples_info(o.samples);
  const acquire::StoreSamples src(s, o.samples);
  store::Grid grid = empty_grid(info);
  std::vector<float> confidence(brdf::kMerlCells);
  std::unique_ptr<acquire::MicrofacetBrdf> model;
  const acquire::ModelResampleStats st = acquire::resample_with_model(
      src, info.wavelengths, {.local = ro, .fit = fo, .confidence_reach = o.confidence_reach}, grid.brdf, confidence,
      &model);
  store::Grid conf = acquire::confidence_grid(confidence, info.wavelengths);
  grid.provenance.source_file = conf.provenance.source_file = o.store + ":" + o.samples;
  grid.provenance.importer =
      "resample model=" + model_json(*model).dump() +
      fmt::format(" confidence_reach={} mapping={} k={} weights={}", o.confidence_reach, o.mapping, o.k, o.weights);
  conf.provenance.importer = "resample confidence of " + o.output;
  const std::string what = save_prior_grids(grid, conf, o.output, conf_out, o.replace);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j = report_head(info, st.filled_cells);
    j["observed_cells"] = st.fit.observed_cells;
    j["shape_cells"] = st.fit.shape_cells;
    j["evaluations"] = st.fit.evaluations;
    j["downweighted"] = st.fit.downweighted;
    j["fit_relative_rms"] = st.fit.relative_rms;
    j["seconds"] = seconds;
    j["fit_seconds"] = st.fit_seconds;
    j["model"] = model_json(*model);
    j["output"] = o.output;
    j["confidence"] = conf_out;
    j["threads"] = omp_get_max_threads();
    print_json(j);
    return;
  }
  std::string shapes;
  for (const auto& sh : model->shapes())
    shapes += fmt::format(" alpha {:.4g}, {} {:.4g};", sh.alpha, o.fresnel == "schlick" ? "F0" : "eta", sh.fresnel);
  fmt::print(
      "resampled {} samples of {} on a fitted {} model ({} lobe(s):{} relative RMS of the fit {:.3f}) onto all {} "
      "valid cells in {:.2f} s: {}; confidence in {}\n",
      info.size, o.samples, o.model, o.lobes, shapes, st.fit.relative_rms, st.filled_cells, seconds, what, conf_out);
}

// A resolved -k: the count, or the leave-one-out choice with its table (JSON) and its provenance words.
struct ResolvedK {
  std::size_t k = 32;
  Json report;             // null unless -k auto
  std::string provenance;  // "k=K", with how it was chosen for -k auto
};

ResolvedK resolve_k(const ResampleCliOptions& o, acquire::ResampleOptions ro) {
  if (o.k != "auto") {
    std::size_t used = 0;
    ResolvedK r;
    try {
      r.k = std::stoul(o.k, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != o.k.size())
      throw UsageError("-k: give a count of neighbours or 'auto', got '" + o.k + "'");
    r.provenance = fmt::format("k={}", r.k);
    return r;
  }
  const acquire::BandwidthOptions b{.held_out = o.k_held_out,
                                    .criterion = acquire::parse_bandwidth_criterion(o.k_criterion)};
  const acquire::BandwidthChoice c = acquire::choose_bandwidth(store::Store::open(o.store), o.samples, ro, b);
  return {c.k, acquire::bandwidth_choice_json(c, b), acquire::bandwidth_provenance(c, b)};
}

void run_resample(ResampleCliOptions o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(o.max_gap_deg > 0 && o.max_gap_deg <= 180)) throw UsageError("--max-gap: give degrees in (0, 180]");
  acquire::ResampleOptions ro{.mapping = acquire::parse_mapping(o.mapping),
                              .weights = acquire::parse_weights(o.weights),
                              .power = o.power,
                              .max_gap = o.max_gap_deg * std::numbers::pi / 180};
  if (o.k_held_out < 1) throw UsageError("--k-held-out: give at least 1");
  acquire::parse_bandwidth_criterion(o.k_criterion);
  if (o.k == "auto") acquire::check_options(ro);
  check_output(o.output, o.replace);
  if (!o.prior.empty() && !o.model.empty()) throw UsageError("resample: give --prior or --model, not both");
  const ResolvedK rk = resolve_k(o, ro);
  ro.k = rk.k;
  acquire::check_options(ro);
  o.k = rk.provenance.substr(2);  // the prior's and the model's provenance name k as the plain one does
  if (!o.prior.empty()) return run_prior_resample(o, ro);
  if (!o.model.empty()) return run_model_resample(o, ro);
  const store::Store s = store::Store::open(o.store);
  const store::SamplesInfo info = s.samples_info(o.samples);
  const acquire::StoreSamples src(s, o.samples);
  store::Grid grid = empty_grid(info);
  const acquire::GridStats stats = acquire::resample_grid(src, ro, grid.brdf);
  grid.provenance.source_file = o.store + ":" + o.samples;
  // Only Shepard's weights have a power, so the provenance names it only for them.
  const std::string power = ro.weights == acquire::Weights::shepard ? fmt::format(" power={}", o.power) : "";
  grid.provenance.importer = fmt::format("resample mapping={} {} weights={}{} max_gap_deg={}", o.mapping, rk.provenance,
                                         o.weights, power, o.max_gap_deg);
  const std::string what = save_grid(grid, o.output, o.replace, "resample");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j = report_head(info, stats.valid_cells);
    j["seconds"] = seconds;
    j["tree_seconds"] = stats.tree_seconds;
    j["query_seconds"] = stats.query_seconds;
    j["average_seconds"] = stats.average_seconds;
    j["passes"] = stats.passes;
    j["mapping"] = o.mapping;
    j["k"] = rk.k;
    if (!rk.report.is_null()) j["k_auto"] = rk.report;
    j["weights"] = o.weights;
    j["power"] = o.power;
    j["output"] = o.output;
    j["threads"] = omp_get_max_threads();
    print_json(j);
    return;
  }
  fmt::print("resampled {} samples of {} onto {} of {} cells ({} mapping, k = {}{}, {} weights) in {:.2f} s: {}\n",
             info.size, o.samples, stats.valid_cells, brdf::kMerlCells, o.mapping, rk.k,
             rk.report.is_null() ? "" : " chosen by leave-one-out", o.weights, seconds, what);
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
                  "best by leave-one-out (docs/resampling.md)")
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
  auto* power =
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
  cmd->add_option(
         "--confidence-reach", o->confidence_reach,
         "--prior, --model: the kd-tree estimate's weight falls from 1 at a sample to 0 at this fraction of --max-gap")
      ->capture_default_str();
  cmd->add_flag("--prior-residuals", o->prior_residuals,
                "--prior: add the kd-tree estimate of the residuals against the prior fit (as --model) instead of "
                "blending the two");
  cmd->add_flag("--kd-tree-in-cap", o->kd_tree_in_cap,
                "--prior: keep the kd-tree estimate in the theta_h rows below the lowest sampled one (the unseen cap "
                "round the specular peak) instead of the prior alone there (docs/prior.md)");
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->add_flag("--json", o->json, "Print one JSON object (samples, cells, valid_cells, seconds)");
  cmd->callback([o, power, k_criterion, k_held_out] {
    if (power->count() > 0 && o->weights != "shepard") throw UsageError("--power: only Shepard's weights have a power");
    if ((k_criterion->count() > 0 || k_held_out->count() > 0) && o->k != "auto")
      throw UsageError("--k-criterion, --k-held-out: only with -k auto");
    run_resample(*o);
  });
}

}  // namespace specula::app
