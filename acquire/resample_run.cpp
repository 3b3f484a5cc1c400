#include "specula/acquire/resample_run.h"

#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <numbers>

#include "specula/acquire/base_resample.h"
#include "specula/acquire/prior_output.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/retro_band.h"
#include "specula/acquire/retro_rise.h"
#include "specula/acquire/store_samples.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_mapping.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"

namespace specula::acquire {
namespace {

using Json = nlohmann::ordered_json;

double elapsed_seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A grid on the samples' bands and units, every value zero, for a resampler to fill.
store::Grid empty_grid(const store::SamplesInfo& info, const ResampleJob& job) {
  store::Grid grid;
  grid.wavelengths = info.wavelengths;
  grid.units = info.units;
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  grid.provenance.source_file = job.store + ":" + job.samples;
  return grid;
}

// What every kind of resampling reports first: the samples read and the grid's cells.
Json report_head(const store::SamplesInfo& info, std::uint64_t valid_cells) {
  return {{"samples", info.size}, {"bands", info.bands}, {"cells", brdf::kMerlCells}, {"valid_cells", valid_cells}};
}

// The k the job resamples with and how it came to be: the leave-one-out choice when asked for one.
struct ChosenK {
  std::size_t k = 0;
  Json report;             // null unless chosen by leave-one-out
  std::string provenance;  // "k=K", with how it was chosen
};

ChosenK choice_of(const BandwidthChoice& c, const BandwidthOptions& b) {
  return {c.k, bandwidth_choice_json(c, b), bandwidth_provenance(c, b)};
}

ChosenK given_k(std::size_t k) { return {k, nullptr, fmt::format("k={}", k)}; }

// The common words of every provenance: the mapping, k and the weights.
std::string local_words(const brdf::ResampleOptions& o, const ChosenK& k) {
  return fmt::format("mapping={} {} weights={}", brdf::mapping_name(o.mapping), k.provenance,
                     brdf::weights_name(o.weights));
}

void add_k_auto(Json& j, const ChosenK& k) {
  if (!k.report.is_null()) j["k_auto"] = k.report;
}

ResampleOutcome plain(const ResampleJob& job, const store::Store& s, const store::SamplesInfo& info) {
  const auto t0 = std::chrono::steady_clock::now();
  const StoreSamples src(s, job.samples);
  const brdf::SampleTree tree(src, job.local.mapping);
  const double tree_seconds = elapsed_seconds(t0);
  brdf::ResampleOptions o = job.local;
  ChosenK k = given_k(o.k);
  if (job.k_auto) {
    brdf::ResampleOptions at_most = o;
    at_most.k = job.k_auto->ladder.empty() ? o.k : job.k_auto->ladder.back();
    k = choice_of(choose_bandwidth(tree, src, at_most, *job.k_auto), *job.k_auto);
    o.k = k.k;
  }
  ResampleOutcome out{.grid = empty_grid(info, job)};
  brdf::GridStats stats = brdf::resample_grid(tree, src, o, out.grid.brdf);
  stats.tree_seconds = tree_seconds;
  // Only Shepard's weights have a power, so the provenance names it only for them.
  const std::string power = o.weights == brdf::Weights::shepard ? fmt::format(" power={}", o.power) : "";
  out.grid.provenance.importer =
      fmt::format("resample {}{} max_gap_deg={:.6g}", local_words(o, k), power, o.max_gap * 180 / std::numbers::pi);
  const double seconds = elapsed_seconds(t0);
  out.report = report_head(info, stats.valid_cells);
  out.report["seconds"] = seconds;
  out.report["tree_seconds"] = stats.tree_seconds;
  out.report["query_seconds"] = stats.query_seconds;
  out.report["average_seconds"] = stats.average_seconds;
  out.report["passes"] = stats.passes;
  out.report["mapping"] = brdf::mapping_name(o.mapping);
  out.report["k"] = k.k;
  add_k_auto(out.report, k);
  out.report["weights"] = brdf::weights_name(o.weights);
  out.report["power"] = o.power;
  out.summary =
      fmt::format("resampled {} samples of {} onto {} of {} cells ({} mapping, k = {}{}, {} weights) in {:.2f} s",
                  info.size, job.samples, stats.valid_cells, brdf::kMerlCells, brdf::mapping_name(o.mapping), k.k,
                  k.report.is_null() ? "" : " chosen by leave-one-out", brdf::weights_name(o.weights), seconds);
  return out;
}

// The k of a prior's or a model's kd-tree estimate: given, or chosen on a tree of its own.
ChosenK resolved_k(const ResampleJob& job, const store::Store& s) {
  if (!job.k_auto) return given_k(job.local.k);
  return choice_of(choose_bandwidth(s, job.samples, job.local, *job.k_auto), *job.k_auto);
}

// The steps a prior's resample takes on the blended grid, in order, and what each did.
struct FinalSteps {
  std::optional<PeakRowsChoice> peak;
  int peak_rows = 0;
  std::optional<LogResidualOptions> log_residuals;
  std::optional<LogResidualStats> corrected;
  std::optional<std::size_t> peak_settled, pole_settled;
  std::optional<std::vector<double>> risen;
};

// The peak's rows chosen, the log residuals multiplied in, the peak's rows and the retro pole settled and the band's
// rise applied to grid, as m asks.
FinalSteps final_steps(const PriorMethod& m, const BrdfPrior& prior, const brdf::SampleSource& src,
                       const PriorResampleStats& st, std::optional<LogResidualOptions> log_residuals, double eps,
                       std::span<float> grid) {
  const std::size_t bands = src.bands();
  FinalSteps f{.log_residuals = std::move(log_residuals)};
  if (m.peak_auto) f.peak = choose_peak_rows(src, grid, bands, *m.peak_auto);
  f.peak_rows = f.peak ? f.peak->rows : m.peak_rows;
  if (f.log_residuals) {
    f.log_residuals->ring_rows = f.peak_rows;
    f.log_residuals->ring_from = st.unseen_cap;
    f.corrected = correct_by_log_residuals(src, *f.log_residuals, eps, grid);
  }
  const std::vector<double> keep = f.peak ? row_keeps(*f.peak) : sin2_keeps(m.peak_rows);
  if (std::ranges::any_of(keep, [](double k) { return k < 1; }))
    f.peak_settled = settle_peak_rows(grid, bands, st.unseen_cap, keep);
  if (m.retro_pole && st.unseen_retro_rows > 0) f.pole_settled = settle_retro_pole(grid, bands, st.unseen_retro_rows);
  if (m.retro_rise) f.risen = raise_retro_band(grid, bands, prior.retro_rise, st.unseen_retro_rows);
  return f;
}

// " keep=K0,K1,.." of the chosen groups, when some group is settled.
std::string group_keeps(const PeakRowsChoice& c) {
  if (std::ranges::all_of(c.groups, [](const PeakRowsGroup& g) { return g.keep >= 1; })) return "";
  std::string out = " keep=";
  for (const PeakRowsGroup& g : c.groups) out += fmt::format("{}{:.3g}", &g == &c.groups.front() ? "" : ",", g.keep);
  return out;
}

// The provenance words of the final steps: "log_residuals=... peak_rows=... retro_pole=... retro_rise=...".
std::string final_words(const FinalSteps& f, int retro_rows) {
  const auto rows = [&](bool on, int n) { return on ? fmt::format("on rows={}", n) : std::string("off"); };
  return fmt::format("log_residuals={} peak_rows={}{} retro_pole={} retro_rise={}",
                     f.corrected ? fmt::format("on radius={} passes={} carried_rows={}", f.log_residuals->radius,
                                               f.log_residuals->passes, f.corrected->carried_rows)
                                 : std::string("off"),
                     rows(bool(f.peak_settled), f.peak_rows), f.peak ? group_keeps(*f.peak) + " chosen" : "",
                     rows(bool(f.pole_settled), retro_rows),
                     f.risen && f.risen->empty() ? std::string("none") : rows(bool(f.risen), retro_rows));
}

// The final steps' fields of the --json report.
void add_final_steps(Json& report, const FinalSteps& f, int retro_rows) {
  if (f.corrected) report["log_residuals"] = log_residuals_json(*f.corrected, *f.log_residuals);
  if (f.peak_settled) report["peak_rows"] = {{"rows", f.peak_rows}, {"settled_cells", *f.peak_settled}};
  if (f.peak_settled && f.peak) report["peak_rows"]["keep"] = row_keeps(*f.peak);
  if (f.peak) report["peak_rows_auto"] = peak_rows_choice_json(*f.peak);
  if (f.pole_settled) report["retro_pole"] = {{"rows", retro_rows}, {"settled_cells", *f.pole_settled}};
  if (f.risen) report["retro_rise"] = {{"rows", retro_rows}, {"factors", *f.risen}};
}

ResampleOutcome with_prior(const ResampleJob& job, const PriorMethod& m, const store::Store& s,
                           const store::SamplesInfo& info) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto spec = store::parse_object_spec(m.prior);
  if (!spec) throw UsageError("resample: prior '" + m.prior + "': give STORE.h5:PRIOR");
  const store::Store prior_store = store::Store::open(spec->file);
  const BrdfPrior prior = read_prior_tables(prior_store, spec->name);  // components streamed by the fit
  if (m.retro_rise && prior.retro_rise.empty())
    throw InputError("resample: prior '" + m.prior +
                     "' holds no retro rise maps (written before they were learned, version <= 3); build it again "
                     "with specula prior build, or resample without --retro-rise");
  ChosenK k = resolved_k(job, s);
  PriorResampleOptions po{.local = job.local,
                          .fit = m.fit,
                          .confidence_reach = m.confidence_reach,
                          .residuals = m.residuals,
                          .prior_in_cap = m.prior_in_cap,
                          .log_blend = m.log_blend,
                          .ceiling = m.ceiling,
                          .energy_bound = m.energy_bound};
  po.local.k = k.k;
  const StoreSamples src(s, job.samples);
  const ComponentSource components = store_components(prior_store, spec->name);
  std::optional<ReachChoice> reach;
  std::optional<LogResidualOptions> log_residuals = m.residuals ? std::nullopt : m.log_residuals;
  if (m.reach_auto) {
    ReachOptions ro = *m.reach_auto;
    if (m.retro_residuals_auto && log_residuals) ro.retro_residuals = *log_residuals;
    reach = choose_confidence_reach(src, prior, components, po, ro);
    if (!reach->k_rows.empty()) k = given_k(reach->k);  // the reach's provenance names the ladder it came from
    po.local.k = k.k;
    if (reach->retro_residuals) log_residuals->into_retro_band = reach->retro_residuals->carried;
    po.confidence_reach = reach->reach;
    po.reach_by_theta_h = reach_by_theta_h(*reach);
    po.retro_weight = reach->retro_weight;
    po.retro_weight_by_theta_h = retro_weight_by_theta_h(*reach);
    po.retro_continued = reach->retro_continued;
    po.blend_epsilon = reach->epsilon;
  }
  std::optional<CapWeightChoice> cap;
  if (m.cap_auto && m.prior_in_cap && !m.residuals) {
    cap = choose_cap_weight(src, prior, components, po, *m.cap_auto);
    po.cap_weight = cap->weight;
    if (!reach) po.blend_epsilon = cap->epsilon;
  }
  ResampleOutcome out{.grid = empty_grid(info, job)};
  std::vector<float> confidence(brdf::kMerlCells);
  const PriorResampleStats st = resample_with_prior(src, prior, components, po, out.grid.brdf, confidence);
  const double eps = po.blend_epsilon.value_or(prior.epsilon);
  const FinalSteps fin = final_steps(m, prior, src, st, log_residuals, eps, out.grid.brdf);
  out.confidence = confidence_grid(confidence, info.wavelengths);
  out.confidence->provenance.source_file = out.grid.provenance.source_file;
  out.grid.provenance.importer = fmt::format(
      "resample prior={} lambda={} prior_weights={} {} prior_in_cap={}{} ceiling={} energy_bound={} blend={} "
      "{} {}",
      m.prior, m.fit.lambda, prior_weights_name(m.fit.weights),
      reach ? reach_provenance(*reach, *m.reach_auto) : fmt::format("confidence_reach={}", m.confidence_reach),
      m.prior_in_cap, cap ? fmt::format(" cap_weight={}", cap->weight) : std::string(),
      !m.ceiling              ? "off"
      : prior.ceiling.empty() ? "none"
                              : "on",
      m.energy_bound ? fmt::format("on floor={} kappa={}", m.energy_bound->floor, m.energy_bound->kappa)
                     : std::string("off"),
      m.log_blend ? fmt::format("log eps={:.3g}", eps) : std::string("linear"), final_words(fin, st.unseen_retro_rows),
      local_words(po.local, k));
  const double seconds = elapsed_seconds(t0);
  out.report = report_head(info, st.filled_cells);
  out.report["k"] = po.local.k;
  out.report["observed_cells"] = st.observed_cells;
  out.report["bounded_cells"] = st.bounded_cells;
  out.report["energy_bounded_cells"] = st.energy_bounded_cells;
  out.report["seconds"] = seconds;
  out.report["fit_seconds"] = st.fit_seconds;
  out.report["prior"] = m.prior;
  out.report["confidence_reach"] = po.confidence_reach;
  out.report["blend"] = m.log_blend ? "log" : "linear";
  out.report["blend_epsilon"] = eps;
  add_final_steps(out.report, fin, st.unseen_retro_rows);
  if (reach) out.report["confidence_reach_auto"] = reach_choice_json(*reach, *m.reach_auto);
  if (cap) out.report["cap_weight_auto"] = cap_weight_json(*cap);
  add_k_auto(out.report, k);
  out.summary = fmt::format(
      "resampled {} samples of {} with prior {} onto all {} valid cells ({} observed; kd-tree reach {}{}) in {:.2f} s",
      info.size, job.samples, m.prior, st.filled_cells, st.observed_cells, po.confidence_reach,
      reach ? " chosen by holdout" : "", seconds);
  return out;
}

// The fitted model as JSON: its kind, each lobe's shape, and the albedos per band.
Json model_json(const MicrofacetBrdf& m) {
  Json lobes = Json::array();
  for (std::size_t j = 0; j < m.shapes().size(); ++j) {
    const Eigen::VectorXd& s = m.specular()[j];
    lobes.push_back({{"alpha", m.shapes()[j].alpha},
                     {m.kind().fresnel == FresnelKind::schlick ? "f0" : "eta", m.shapes()[j].fresnel},
                     {"albedo", std::vector<double>(s.begin(), s.end())}});
  }
  return {{"distribution", distribution_name(m.kind().distribution)},
          {"shadowing", shadowing_name(m.kind().shadowing)},
          {"fresnel", fresnel_name(m.kind().fresnel)},
          {"diffuse", std::vector<double>(m.diffuse().begin(), m.diffuse().end())},
          {"lobes", lobes}};
}

// "Lobe(s): alpha A, F0 F; ..." of the summary line.
std::string shapes_words(const MicrofacetBrdf& m) {
  std::string words;
  for (const auto& sh : m.shapes())
    words += fmt::format(" alpha {:.4g}, {} {:.4g};", sh.alpha, m.kind().fresnel == FresnelKind::schlick ? "F0" : "eta",
                         sh.fresnel);
  return words;
}

ResampleOutcome with_model(const ResampleJob& job, const ModelMethod& m, const store::Store& s,
                           const store::SamplesInfo& info) {
  const auto t0 = std::chrono::steady_clock::now();
  const ChosenK k = resolved_k(job, s);
  ModelResampleOptions mo{.local = job.local, .fit = m.fit, .confidence_reach = m.confidence_reach};
  mo.local.k = k.k;
  const StoreSamples src(s, job.samples);
  ResampleOutcome out{.grid = empty_grid(info, job)};
  std::vector<float> confidence(brdf::kMerlCells);
  std::unique_ptr<MicrofacetBrdf> model;
  const ModelResampleStats st = resample_with_model(src, info.wavelengths, mo, out.grid.brdf, confidence, &model);
  out.confidence = confidence_grid(confidence, info.wavelengths);
  out.confidence->provenance.source_file = out.grid.provenance.source_file;
  const Json mj = model_json(*model);
  out.grid.provenance.importer = "resample model=" + mj.dump() +
                                 fmt::format(" confidence_reach={} {}", m.confidence_reach, local_words(mo.local, k));
  const double seconds = elapsed_seconds(t0);
  out.report = report_head(info, st.filled_cells);
  out.report["observed_cells"] = st.fit.observed_cells;
  out.report["shape_cells"] = st.fit.shape_cells;
  out.report["evaluations"] = st.fit.evaluations;
  out.report["downweighted"] = st.fit.downweighted;
  out.report["fit_relative_rms"] = st.fit.relative_rms;
  out.report["seconds"] = seconds;
  out.report["fit_seconds"] = st.fit_seconds;
  out.report["model"] = mj;
  add_k_auto(out.report, k);
  out.summary = fmt::format(
      "resampled {} samples of {} on a fitted {} model ({} lobe(s):{} relative RMS of the fit {:.3f}) onto all {} "
      "valid cells in {:.2f} s",
      info.size, job.samples, distribution_name(m.fit.kind.distribution), m.fit.lobes, shapes_words(*model),
      st.fit.relative_rms, st.filled_cells, seconds);
  return out;
}

}  // namespace

void check_job(const ResampleJob& job) {
  if (!(job.local.max_gap > 0 && job.local.max_gap <= std::numbers::pi))
    throw UsageError(fmt::format("resample: max_gap = {:g} degrees: give degrees in (0, 180]",
                                 job.local.max_gap * 180 / std::numbers::pi));
  try {
    check_options(job.local);
  } catch (const UsageError& e) {
    throw UsageError(std::string("resample: ") + e.what());
  }
  const auto reach = [](double r) {
    if (!(r > 0 && r <= 1))
      throw UsageError(fmt::format("resample: confidence_reach = {:g}: give a fraction of max_gap in (0, 1]", r));
  };
  if (const auto* m = std::get_if<PriorMethod>(&job.method)) {
    reach(m->confidence_reach);
    if (!m->peak_auto && (m->peak_rows < 0 || m->peak_rows >= brdf::kMerlThetaH))
      throw UsageError(fmt::format("resample: peak_rows = {}: give a count of theta_h rows in [0, {}) or 'auto'",
                                   m->peak_rows, brdf::kMerlThetaH));
  }
  if (const auto* m = std::get_if<ModelMethod>(&job.method)) {
    reach(m->confidence_reach);
    if (m->fit.lobes < 1 || m->fit.lobes > 2)
      throw UsageError(fmt::format("resample: lobes = {}: give 1 or 2 microfacet lobes", m->fit.lobes));
  }
}

ResampleOutcome run_resample(const ResampleJob& job) {
  check_job(job);
  const store::Store s = store::Store::open(job.store);
  const store::SamplesInfo info = s.samples_info(job.samples);
  ResampleOutcome out;
  if (const auto* m = std::get_if<PriorMethod>(&job.method))
    out = with_prior(job, *m, s, info);
  else if (const auto* m = std::get_if<ModelMethod>(&job.method))
    out = with_model(job, *m, s, info);
  else
    out = plain(job, s, info);
  out.report["threads"] = omp_get_max_threads();
  return out;
}

}  // namespace specula::acquire
