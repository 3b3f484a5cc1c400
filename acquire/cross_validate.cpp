#include "specula/acquire/cross_validate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <random>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {

namespace {

// The summed errors of one configuration's predictions, e2[j] < 0 where sample j had no prediction.
CrossValidationRow summarise(brdf::Mapping mapping, std::size_t k, brdf::Weights weights, std::span<const double> e2,
                             std::span<const double> t2) {
  CrossValidationRow row{mapping, k, weights};
  double err = 0, ref = 0;
  std::vector<double> per_sample;
  for (std::size_t j = 0; j < e2.size(); ++j) {
    if (e2[j] < 0) continue;
    ++row.predicted;
    err += e2[j];
    ref += t2[j];
    if (t2[j] > 0) per_sample.push_back(std::sqrt(e2[j] / t2[j]));
  }
  row.rel_rms = ref > 0 ? std::sqrt(err / ref) : 0.0;
  if (!per_sample.empty()) {
    std::nth_element(per_sample.begin(), per_sample.begin() + std::ptrdiff_t(per_sample.size() / 2), per_sample.end());
    row.median_rel = per_sample[per_sample.size() / 2];
  }
  return row;
}

}  // namespace

CrossValidation cross_validate(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                               const CrossValidationOptions& o) {
  if (!(o.holdout > 0 && o.holdout < 1))
    throw UsageError(fmt::format("cross_validate: holdout must be a fraction in (0, 1), got {}", o.holdout));
  for (const auto k : o.ks)
    if (k < 1) throw UsageError("cross_validate: every k must be at least 1");
  const std::size_t b = bands;
  if (b == 0 || angles.size() % 4 != 0 || values.size() != angles.size() / 4 * b)
    throw UsageError(fmt::format("cross_validate: needs n x 4 angles and n x {} values, got {} angles and {} values", b,
                                 angles.size(), values.size()));
  const std::size_t n = angles.size() / 4;
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(o.seed);
  std::shuffle(order.begin(), order.end(), rng);
  const auto held = std::size_t(std::llround(o.holdout * double(n)));
  if (held < 1 || held >= n)
    throw InputError(fmt::format("{} samples leave nothing to hold out at holdout {}", n, o.holdout));
  std::vector<double> train_a, test_a;
  std::vector<float> train_v, test_v;
  for (std::size_t j = 0; j < n; ++j) {
    const std::size_t i = order[j];
    auto& a = j < held ? test_a : train_a;
    auto& v = j < held ? test_v : train_v;
    a.insert(a.end(), angles.begin() + std::ptrdiff_t(4 * i), angles.begin() + std::ptrdiff_t(4 * i + 4));
    v.insert(v.end(), values.begin() + std::ptrdiff_t(i * b), values.begin() + std::ptrdiff_t((i + 1) * b));
  }
  CrossValidation out;
  out.samples = n;
  out.held_out = held;
  Progress progress("cross-validating", 3 * o.ks.size() * 5 * held);  // mappings x k x weightings
  for (const auto mapping : {brdf::Mapping::standard, brdf::Mapping::marschner, brdf::Mapping::halfdiff}) {
    const brdf::MemorySamples train(train_a, train_v, b);
    const auto tree = std::make_shared<const brdf::SampleTree>(train, mapping);
    for (const auto k : o.ks)
      for (const auto weights : {brdf::Weights::mean, brdf::Weights::shepard, brdf::Weights::renka,
                                 brdf::Weights::wendland, brdf::Weights::loess}) {
        if (k == 1 && weights != brdf::Weights::mean) continue;  // one neighbour: the same prediction
        // No support limit: every held-out sample is predicted from its k nearest, however far.
        const brdf::Resampler r(tree, train_v, b, {.mapping = mapping, .k = k, .weights = weights, .max_gap = 10});
        std::vector<double> e2(held, -1), t2(held, 0);
        parallel_for(
            held, [&] { return std::vector<float>(b); },
            [&](std::size_t j, std::vector<float>& pred) {
              const double* a = test_a.data() + 4 * j;
              if (!r.predict(brdf::StdAngles{a[0], a[1], a[2], a[3]}, pred)) return;
              double se = 0, st = 0;
              for (std::size_t q = 0; q < b; ++q) {
                const double t = test_v[j * b + q], e = double(pred[q]) - t;
                se += e * e;
                st += t * t;
              }
              e2[j] = se;
              t2[j] = st;
            },
            16);
        check_interrupt();
        progress.advance(k == 1 ? 5 * held : held);
        out.rows.push_back(summarise(mapping, k, weights, e2, t2));
      }
  }
  return out;
}

}  // namespace specula::acquire
