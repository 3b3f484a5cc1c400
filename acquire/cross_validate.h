#pragma once
// Leave-out cross-validation of resampling (reference §5.3): a fixed random share of scattered samples is held
// out, the rest resampled (core/brdf_resample.h) at the held-out configurations for every mapping, k and
// weighting, and the prediction error of each configuration summed. `specula eval-resample` prints the rows.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "specula/core/brdf_resample.h"

namespace specula::acquire {

struct CrossValidationOptions {
  double holdout = 0.1;                              ///< share of the samples held out, in (0, 1)
  std::uint64_t seed = 0;                            ///< seed of the shuffle choosing them
  std::vector<std::size_t> ks = {1, 4, 16, 32, 64};  ///< neighbour counts, each at least 1
};

/// The prediction error of one mapping, k and weighting over the held-out samples it could predict.
struct CrossValidationRow {
  brdf::Mapping mapping = brdf::Mapping::standard;
  std::size_t k = 1;
  brdf::Weights weights = brdf::Weights::mean;  ///< mean for k = 1 (the nearest sample; any weights predict the same)
  double rel_rms = 0;         ///< sqrt(sum (pred - true)^2 / sum true^2) over predicted held-out samples and bands
  double median_rel = 0;      ///< median over predicted held-out samples of |pred - true| / |true| (spectra as vectors)
  std::size_t predicted = 0;  ///< held-out samples predicted (all: no support limit)
};

/// What a cross-validation held out and found.
struct CrossValidation {
  std::size_t samples = 0, held_out = 0;
  std::vector<CrossValidationRow>
      rows;  ///< standard, marschner, halfdiff; per mapping each k; per k mean, shepard, renka, wendland, loess
};

/// Shuffles the n samples (angles n x 4, values n x bands) with a generator seeded by o.seed, holds out the first
/// round(holdout n), predicts each from its k nearest remaining samples (however far) for every mapping, k and
/// weighting; on all threads with the same rows for any thread count; progress shown, Interrupted between
/// configurations. UsageError for holdout outside (0, 1), a k of 0 or mismatched sizes; InputError when the
/// holdout leaves no sample to hold out or none to train on.
CrossValidation cross_validate(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                               const CrossValidationOptions& o);

}  // namespace specula::acquire
