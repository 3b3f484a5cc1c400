#pragma once
// Synthetic measurements of an analytic spectral BRDF (core/brdf_models.h): the model evaluated at scattered
// configurations (a simulated scan's, acquire/scan.h, or random ones) with multiplicative Gaussian noise, as a
// capture would record them. Ground truth for resampling tests, the study and the benchmark; `specula
// synth-samples` appends the batches to a store.
// Placement: acquire rather than core, beside the scan that produces the configurations: the parallel loop
// (core/parallel.h) needs the including library's OpenMP, and core stays Eigen-only.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "specula/acquire/scan.h"
#include "specula/core/brdf_models.h"

namespace specula::acquire {

/// Samples per noise generator: the noise of batch `batch` is drawn in pieces of this many consecutive samples,
/// piece p from a generator seeded by (seed, batch, p), so the values do not depend on the thread count.
inline constexpr std::size_t kNoisePiece = 4096;

/// `model` at n configurations (angles n x 4: theta_i, phi_i, theta_o, phi_o) into values (n x bands), each value
/// times (1 + noise N(0, 1)) drawn per kNoisePiece samples from (seed, batch); on all threads, the same result for
/// any thread count; noise 0 gives brdf::evaluate_at. UsageError for noise outside [0, 1] or mismatched sizes.
void evaluate_noisy(const brdf::SpectralModel& model, std::span<const double> angles, std::span<float> values,
                    double noise, std::uint64_t seed, std::uint64_t batch);

/// n configurations with both directions uniform over the hemisphere's solid angle (cos theta uniform in [0, 1],
/// phi uniform in [-pi, pi)), drawn from one generator seeded by (seed, block), into angles (resized to n x 4).
void random_configurations(std::size_t n, std::uint64_t seed, std::uint64_t block, std::vector<double>& angles);

/// Even thinning of a stream of `total` samples to `count` (count < total): keeps those of the n = angles.size() / 4
/// samples of this batch whose running index `seen` (advanced by n) crosses a multiple of total / count, compacting
/// angles in place; over the whole stream exactly `count` are kept. Returns how many of this batch were kept.
std::size_t thin_evenly(std::vector<double>& angles, std::size_t& seen, std::size_t count, std::size_t total);

/// Where synthetic samples are taken: at the scan of `rig` (thinned evenly to `count` when 0 < count < all it sees) or
/// at `count` random configurations (random_configurations, 2^20 per block); `noise` and `seed` as evaluate_noisy().
struct SampleSynthesis {
  enum class Geometry { scan, random } geometry = Geometry::scan;
  ScanRig rig;
  std::size_t count = 0;
  double noise = 0;
  std::uint64_t seed = 1;
};

/// What synthesize_samples() produced.
struct SynthesisCount {
  std::size_t samples = 0;
  std::size_t pixels = 0;  ///< scan: sphere pixels seen
};

/// Synthetic samples of `model` (angles n x 4, values n x bands) handed to `sink` batch by batch in a fixed order (one
/// batch per light of the scan, or per block of random configurations), with progress and an interruption check
/// between batches. The settings are not checked here (check_rig, count, noise: the caller's).
SynthesisCount synthesize_samples(const brdf::SpectralModel& model, const SampleSynthesis& settings,
                                  const std::function<void(std::span<const double>, std::span<const float>)>& sink);

}  // namespace specula::acquire
