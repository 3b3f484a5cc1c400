// specula.resample: a store's scattered BRDF samples onto the MERL grid (acquire::run_resample, what `specula
// resample` runs), plainly, with a learned prior or on a fitted model; the grid as a specula.Grid and the report of
// `resample --json` as a dict with the per-cell confidence as an array.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <numbers>

#include "python/common.h"
#include "specula/acquire/prior_reach.h"
#include "specula/acquire/resample_run.h"

namespace specula::python {
namespace {

// The store's file: a specula.Store's path or an existing path.
std::string store_path(const StoreArg& store) {
  if (py::isinstance<PyStore>(store)) return store.cast<PyStore&>().path().string();
  if (py::isinstance<py::list>(store) || py::isinstance<py::tuple>(store))
    throw UsageError("resample: give one store (a path or a specula.Store)");
  return existing_file(store).string();
}

// How `k` was given: a count, "auto" (leave-one-out over the samples) or "holdout" (with a prior: chosen with the
// reach by its holdout).
enum class KGiven { count, loo, holdout };

// `k` as a count (the default count for "auto" and "holdout"), and how it was given into `how`.
std::size_t neighbour_count(const CountOrAuto& k, KGiven& how) {
  const std::string word = py::isinstance<py::str>(k) ? k.cast<std::string>() : "";
  how = word == "auto" ? KGiven::loo : word == "holdout" ? KGiven::holdout : KGiven::count;
  if (how != KGiven::count) return brdf::ResampleOptions{}.k;
  if (py::isinstance<py::int_>(k) && !py::isinstance<py::bool_>(k) && k.cast<long long>() > 0)
    return k.cast<std::size_t>();
  throw UsageError(fmt::format("resample: k = {}: give a count of neighbours, 'auto' or (with a prior) 'holdout'",
                               py::repr(k).cast<std::string>()));
}

// peak_rows of a prior: "auto" (chosen from the scan) or a count of theta_h rows.
void set_peak_rows(const CountOrAuto& peak_rows, acquire::PriorMethod& prior) {
  if (py::isinstance<py::str>(peak_rows) && peak_rows.cast<std::string>() == "auto") return;
  if (!py::isinstance<py::int_>(peak_rows) || py::isinstance<py::bool_>(peak_rows))
    throw UsageError(fmt::format("resample: peak_rows = {}: give a count of theta_h rows in [0, 90) or 'auto'",
                                 py::repr(peak_rows).cast<std::string>()));
  prior.peak_auto.reset();
  prior.peak_rows = peak_rows.cast<int>();
}

// The reach of a prior's or a model's confidence: a fraction, "auto" (a prior's holdout), or None (the method's
// default).
void set_reach(const ReachArg& reach, acquire::PriorMethod* prior, acquire::ModelMethod* model) {
  if (reach.is_none()) return;
  const bool auto_reach = py::isinstance<py::str>(reach) && reach.cast<std::string>() == "auto";
  if (!auto_reach && !(py::isinstance<py::float_>(reach) || py::isinstance<py::int_>(reach)))
    throw UsageError("resample: confidence_reach: give a fraction of max_gap in (0, 1], 'auto' or None");
  if (auto_reach && !prior) throw UsageError("resample: confidence_reach='auto' is chosen only with a prior");
  if (prior && !auto_reach) {
    prior->reach_auto.reset();
    prior->confidence_reach = reach.cast<double>();
  }
  if (model) model->confidence_reach = reach.cast<double>();
}

}  // namespace

void init_resample(py::module_& m) {
  m.def(
      "resample",
      [](const StoreArg& store, const std::string& samples, const CountOrAuto& k, const std::string& weights,
         double power, const std::string& mapping, double max_gap, const OptStr& prior, const OptStr& model, int lobes,
         std::optional<double> lambda, const ReachArg& confidence_reach, std::optional<bool> log_residuals,
         const CountOrAuto& peak_rows, bool retro_rise) -> ResampleResult {
        if (!prior.is_none() && !model.is_none()) throw UsageError("resample: give prior or model, not both");
        const bool peak_given = !(py::isinstance<py::str>(peak_rows) && peak_rows.cast<std::string>() == "auto");
        if (prior.is_none() && (lambda || log_residuals || peak_given || retro_rise))
          throw UsageError(fmt::format("resample: {}: only with a prior", lambda          ? "lambda_"
                                                                          : log_residuals ? "log_residuals"
                                                                          : peak_given    ? "peak_rows"
                                                                                          : "retro_rise"));
        if (model.is_none() && lobes != 1) throw UsageError("resample: lobes: only with a model");
        KGiven k_given = KGiven::count;
        acquire::ResampleJob job{.store = store_path(store),
                                 .samples = samples,
                                 .local = {.mapping = brdf::parse_mapping(mapping),
                                           .k = neighbour_count(k, k_given),
                                           .weights = brdf::parse_weights(weights),
                                           .power = power,
                                           .max_gap = max_gap * std::numbers::pi / 180}};
        if (k_given == KGiven::loo) job.k_auto = acquire::BandwidthOptions{};
        if (k_given == KGiven::holdout && prior.is_none())
          throw UsageError("resample: k='holdout' is chosen by a prior's holdout, only with a prior");
        if (!prior.is_none()) {
          acquire::PriorMethod pm{.prior = prior.cast<std::string>()};
          if (lambda) pm.fit.lambda = *lambda;
          set_reach(confidence_reach, &pm, nullptr);
          if (k_given == KGiven::holdout && !pm.reach_auto)
            throw UsageError("resample: k='holdout' is chosen with the reach, so not with a confidence_reach given");
          if (k_given == KGiven::holdout) pm.reach_auto->k_ladder = acquire::kReachKLadder;
          if (!log_residuals.value_or(true)) pm.log_residuals.reset();
          pm.retro_rise = retro_rise;
          set_peak_rows(peak_rows, pm);
          job.method = pm;
        } else if (!model.is_none()) {
          acquire::ModelMethod mm{
              .fit = {.kind = {.distribution = acquire::parse_distribution(model.cast<std::string>())},
                      .lobes = std::size_t(std::max(lobes, 0))}};
          set_reach(confidence_reach, nullptr, &mm);
          job.method = mm;
        } else if (!confidence_reach.is_none()) {
          throw UsageError("resample: confidence_reach: only with a prior or a model");
        }
        acquire::check_job(job);
        acquire::ResampleOutcome r = interruptible([&] { return acquire::run_resample(job); });
        py::dict report = py::module_::import("json").attr("loads")(r.report.dump());
        report["summary"] = r.summary;
        report["confidence"] = py::none();
        if (r.confidence) {
          const py::ssize_t dims[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};
          report["confidence"] = adopt(std::move(r.confidence->brdf), {dims[0], dims[1], dims[2]});
        }
        r.grid.provenance.command_line = python_command_line("resample");
        return ResampleResult(py::make_tuple(py::cast(std::move(r.grid)), report));
      },
      py::arg("store"), py::arg("samples"), py::kw_only(), py::arg("k") = 32, py::arg("weights") = "shepard",
      py::arg("power") = 1.0, py::arg("mapping") = "standard", py::arg("max_gap") = brdf::kDefaultMaxGapDegrees,
      py::arg("prior") = py::none(), py::arg("model") = py::none(), py::arg("lobes") = 1,
      py::arg("lambda_") = py::none(), py::arg("confidence_reach") = py::none(), py::arg("log_residuals") = py::none(),
      py::arg("peak_rows") = "auto", py::arg("retro_rise") = false,
      "Resamples the scattered BRDF samples `samples` of `store` onto the MERL grid as `specula resample` does "
      "(docs/resampling.md, docs/prior.md): the kd-tree's k nearest samples (k a count, 'auto' or, with a prior, "
      "'holdout' as `-k holdout`), weighted by "
      "`weights` (shepard, loess, wendland, renka, mean), cells farther than max_gap degrees from every sample left "
      "without data; with prior='STORE.h5:NAME' a learned prior fitted and blended (every valid cell filled; lambda_ "
      "its Tikhonov weight, 1e-3 when None; log_residuals False leaves out the samples' log residuals multiplied in; "
      "peak_rows: the theta_h rows round the peak settled over phi_d, 'auto' chosen from the scan, a count given, 0 "
      "none; retro_rise True scales the unseen retro band to the rise the prior's map predicts from the "
      "result's shoulder, as `--retro-rise`); "
      "with model='ggx' or 'beckmann' a "
      "Lambertian plus `lobes` microfacet lobes as the base. confidence_reach: the kd-tree's reach as a fraction of "
      "max_gap, 'auto' (a prior's holdout, its default) or None. Returns (grid, report): a specula.Grid in 1/sr and "
      "the fields of `specula resample --json` with 'summary' and 'confidence', (90, 90, 180) float32 per cell (-1 "
      "below the horizon) for a prior or a model, None otherwise. Reads the store's latest committed state; writes "
      "nothing (Store.write_grid saves the grid).");
}

}  // namespace specula::python
