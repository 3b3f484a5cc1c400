// specula eval-resample: leave-out cross-validation of the resampling (reference §5.3): a fixed random share
// of the samples is held out, the rest resampled at the held-out angles for every mapping, k and weighting,
// and the prediction error tabulated.
#include <fmt/format.h>

#include <memory>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/cross_validate.h"
#include "specula/core/error.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct EvalResampleOptions {
  std::string store;
  std::string samples;
  double holdout = 0.1;
  std::uint64_t seed = 0;
  std::vector<std::size_t> k = {1, 4, 16, 32, 64};
  bool json = false;
};

void run_eval_resample(const EvalResampleOptions& o) {
  if (!(o.holdout > 0 && o.holdout < 1)) throw UsageError("--holdout: give a fraction in (0, 1)");
  for (const auto k : o.k)
    if (k < 1) throw UsageError("-k: every value must be at least 1");
  const store::Store s = store::Store::open(o.store);
  const store::SamplesInfo info = s.samples_info(o.samples);
  std::vector<double> angles(4 * info.size);
  std::vector<float> values(info.size * info.bands);
  s.read_samples(o.samples, 0, info.size, angles, values);
  acquire::CrossValidation cv;
  try {
    cv = acquire::cross_validate(angles, values, info.bands, {.holdout = o.holdout, .seed = o.seed, .ks = o.k});
  } catch (const InputError& e) {
    throw InputError(o.samples + ": " + e.what());
  }
  const std::size_t held = cv.held_out;
  auto weights = [](const acquire::CrossValidationRow& r) {
    return r.k == 1 ? std::string("nearest") : std::string(brdf::weights_name(r.weights));
  };
  if (o.json) {
    Json list = Json::array();
    for (const auto& r : cv.rows)
      list.push_back({{"mapping", std::string(brdf::mapping_name(r.mapping))},
                      {"k", r.k},
                      {"weights", weights(r)},
                      {"rel_rms", r.rel_rms},
                      {"median_rel", r.median_rel},
                      {"predicted", r.predicted}});
    Json j;
    j["samples"] = info.size;
    j["held_out"] = held;
    j["seed"] = o.seed;
    j["results"] = std::move(list);
    print_json(j);
    return;
  }
  fmt::print("{}: {} samples, {} held out (seed {}); relative RMS error of the held-out spectra:\n", o.samples,
             info.size, held, o.seed);
  fmt::print("| mapping | k | weights | relative RMS | median relative error |\n|---|---|---|---|---|\n");
  for (const auto& r : cv.rows)
    fmt::print("| {} | {} | {} | {:.4f} | {:.4f} |\n", brdf::mapping_name(r.mapping), r.k, weights(r), r.rel_rms,
               r.median_rel);
}

}  // namespace

void setup_eval_resample(CLI::App& app) {
  auto o = std::make_shared<EvalResampleOptions>();
  auto* cmd =
      app.add_subcommand("eval-resample", "Hold-out cross-validation of resampling per mapping, k and weighting");
  cmd->add_option("store", o->store, "Store holding the samples")->required();
  cmd->add_option("samples", o->samples, "Name of the scattered samples")->required();
  cmd->add_option("--holdout", o->holdout, "Fraction of samples held out")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the random hold-out")->capture_default_str();
  cmd->add_option("-k", o->k, "Neighbour counts to try")->delimiter(',')->capture_default_str();
  cmd->add_flag("--json", o->json, "Print one JSON object with every result");
  cmd->callback([o] { run_eval_resample(*o); });
}

}  // namespace specula::app
