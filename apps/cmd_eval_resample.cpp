// specula eval-resample: leave-out cross-validation of the resampling (reference §5.3): a fixed random share
// of the samples is held out, the rest resampled at the held-out angles for every mapping, k and weighting,
// and the prediction error tabulated.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <memory>
#include <random>

#include "specula/acquire/resample.h"
#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
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

struct Row {
  std::string mapping, weights;
  std::size_t k = 0;
  double rel_rms = 0;     // sqrt(sum (pred - true)^2 / sum true^2) over predicted held-out samples and bands
  double median_rel = 0;  // median over held-out samples of |pred - true| / |true| (spectra as vectors)
  std::size_t predicted = 0;
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
  std::vector<std::size_t> order(info.size);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(o.seed);
  std::shuffle(order.begin(), order.end(), rng);
  const auto held = std::size_t(std::llround(o.holdout * double(info.size)));
  if (held < 1 || held >= info.size)
    throw InputError(fmt::format("{}: {} samples leave nothing to hold out at --holdout {}", o.samples, info.size, o.holdout));
  const std::size_t b = info.bands;
  std::vector<double> train_a, test_a;
  std::vector<float> train_v, test_v;
  for (std::size_t j = 0; j < info.size; ++j) {
    const std::size_t i = order[j];
    auto& a = j < held ? test_a : train_a;
    auto& v = j < held ? test_v : train_v;
    a.insert(a.end(), angles.begin() + std::ptrdiff_t(4 * i), angles.begin() + std::ptrdiff_t(4 * i + 4));
    v.insert(v.end(), values.begin() + std::ptrdiff_t(i * b), values.begin() + std::ptrdiff_t((i + 1) * b));
  }
  std::vector<Row> rows;
  const std::size_t configs = 3 * o.k.size();
  Progress progress("cross-validating", configs * held);
  for (const auto mapping : {acquire::Mapping::standard, acquire::Mapping::marschner, acquire::Mapping::halfdiff}) {
    const acquire::MemorySamples train(train_a, train_v, b);
    const auto tree = std::make_shared<const acquire::SampleTree>(train, mapping);
    for (const auto k : o.k)
      for (const auto weights : {acquire::Weights::mean, acquire::Weights::shepard}) {
        if (k == 1 && weights == acquire::Weights::shepard) continue;  // one neighbour: the same prediction
        // No support limit: every held-out sample is predicted from its k nearest, however far.
        const acquire::Resampler r(tree, train_v, b, {.mapping = mapping, .k = k, .weights = weights, .max_gap = 10});
        std::vector<double> e2(held, -1), t2(held, 0);
#pragma omp parallel
        {
          std::vector<float> out(b);
#pragma omp for schedule(dynamic, 16)
          for (long long jj = 0; jj < static_cast<long long>(held); ++jj) {
            const std::size_t j = std::size_t(jj);
            const double* a = test_a.data() + 4 * j;
            if (!r.predict(brdf::StdAngles{a[0], a[1], a[2], a[3]}, out)) continue;
            double se = 0, st = 0;
            for (std::size_t q = 0; q < b; ++q) {
              const double t = test_v[j * b + q], e = double(out[q]) - t;
              se += e * e;
              st += t * t;
            }
            e2[j] = se;
            t2[j] = st;
          }
        }
        check_interrupt();
        progress.advance(k == 1 ? 2 * held : held);
        double err = 0, ref = 0;
        std::size_t predicted = 0;
        std::vector<double> per_sample;
        for (std::size_t j = 0; j < held; ++j) {
          if (e2[j] < 0) continue;
          ++predicted;
          err += e2[j];
          ref += t2[j];
          if (t2[j] > 0) per_sample.push_back(std::sqrt(e2[j] / t2[j]));
        }
        rows.push_back({std::string(acquire::mapping_name(mapping)),
                        k == 1 ? "nearest" : std::string(acquire::weights_name(weights)), k,
                        ref > 0 ? std::sqrt(err / ref) : 0.0, 0.0, predicted});
        if (!per_sample.empty()) {
          std::nth_element(per_sample.begin(), per_sample.begin() + std::ptrdiff_t(per_sample.size() / 2), per_sample.end());
          rows.back().median_rel = per_sample[per_sample.size() / 2];
        }
      }
  }
  if (o.json) {
    std::string list;
    for (const auto& r : rows)
      list += fmt::format(R"({}{{"mapping":{},"k":{},"weights":{},"rel_rms":{},"median_rel":{},"predicted":{}}})",
                          list.empty() ? "" : ",", json_string(r.mapping), r.k, json_string(r.weights), r.rel_rms,
                          r.median_rel, r.predicted);
    fmt::print(R"({{"samples":{},"held_out":{},"seed":{},"results":[{}]}})"
               "\n",
               info.size, held, o.seed, list);
    return;
  }
  fmt::print("{}: {} samples, {} held out (seed {}); relative RMS error of the held-out spectra:\n", o.samples, info.size,
             held, o.seed);
  fmt::print("| mapping | k | weights | relative RMS | median relative error |\n|---|---|---|---|---|\n");
  for (const auto& r : rows)
    fmt::print("| {} | {} | {} | {:.4f} | {:.4f} |\n", r.mapping, r.k, r.weights, r.rel_rms, r.median_rel);
}

}  // namespace

void setup_eval_resample(CLI::App& app) {
  auto o = std::make_shared<EvalResampleOptions>();
  auto* cmd = app.add_subcommand("eval-resample", "Hold-out cross-validation of resampling per mapping, k and weighting");
  cmd->add_option("store", o->store, "Store holding the samples")->required();
  cmd->add_option("samples", o->samples, "Name of the scattered samples")->required();
  cmd->add_option("--holdout", o->holdout, "Fraction of samples held out")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the random hold-out")->capture_default_str();
  cmd->add_option("-k", o->k, "Neighbour counts to try")->delimiter(',')->capture_default_str();
  cmd->add_flag("--json", o->json, "Print one JSON object with every result");
  cmd->callback([o] { run_eval_resample(*o); });
}

}  // namespace specula::app
