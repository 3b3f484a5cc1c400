#pragma once
// Coding a grid to a perceptual target: the coarsest format-2 step whose decoding the lighting suite
// (codec/suite.h) cannot tell from the grid beyond the target.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "specula/codec/spc.h"
#include "specula/codec/suite.h"

namespace specula::codec {

/// What a perceptual target asks of a transform coding, as the lighting suite measures the grid against its
/// decoding: pooled ΔE00 mean at most `de00_mean`, pooled 95th percentile at most `de00_p95`, and no single
/// condition's mean above `condition_mean`.
struct SpcTarget {
  double de00_mean = 0.5;
  double de00_p95 = 1.5;
  double condition_mean = 1.0;
  int max_trials = 8;     ///< trial codings, 2..32
  double first_step = 1;  ///< the first step tried
};

/// Where a target search ended.
struct SpcTargetReport {
  bool reached = false;  ///< false: no trial met the target; the finest step tried was coded
  int trials = 0;
  double step = 0;                     ///< the step coded
  double de00_mean = 0, de00_p95 = 0;  ///< pooled over the suite, what the coded file renders to
  double worst_mean = 0;               ///< the largest condition mean
  std::string worst_condition;
};

/// Encodes `grid` by the transform method (options.step is ignored) with the coarsest step found to meet `target`
/// under `suite`: from target.first_step, each next step scaled from the last trial's excess (2 to 16 times) until
/// the target is bracketed, then interpolated in log excess against log step until the bracket is within 20 %, at
/// most target.max_trials suite renderings, never finer than codes of 2^27 allow; not meeting it (a basis that
/// cannot express the grid's spectra has an error floor) is reported in `target_report`, not thrown. The same bytes
/// for any thread count.
std::vector<std::uint8_t> encode_spc_to_target(const store::Grid& grid, const SpcBasis& basis,
                                               const SpcTransformOptions& options, const SpcTarget& target,
                                               const LightingSuite& suite, SpcTargetReport& target_report,
                                               SpcReport* report = nullptr, const std::string& source = "");

/// One candidate k of a search over k (encode_spc_choosing_k).
struct SpcKCandidate {
  std::size_t k = 0;
  bool searched = false;   ///< false: a floor probe; true: a target search (the fields below are its result)
  bool floor_met = false;  ///< a floor probe's coding at the finest step met the target
  bool reached = false;
  double first_step = 0, step = 0;
  std::uint64_t bytes = 0;
};

/// Where a search over k ended: the k coded and every candidate probed, in the order probed.
struct SpcKReport {
  std::size_t k = 0;
  std::vector<SpcKCandidate> candidates;
};

/// The basis of k spectra, for each k a search over k may try.
using SpcBasisOfK = std::function<SpcBasis(std::size_t k)>;

/// Encodes `grid` at the k in 1..k_max whose target coding (encode_spc_to_target) is the smallest file meeting
/// `target`. Floors: k0 is the smallest k whose coding at the finest step meets the target, found by bisection over
/// 1..k_max (bases of a family are nested, so the floor falls with k; k_max itself is not probed). Sizes: from k0
/// upwards each k is coded to the target, the first from target.first_step and each next from the step the last met
/// one chose, until two successive k give no smaller file than the best so far (or k_max). If none meets the
/// target, the first k searched is coded and reported as not reached. Deterministic; the same bytes for any thread
/// count. `basis_of_k` must return bases on the grid's wavelengths; k in the report is its argument.
std::vector<std::uint8_t> encode_spc_choosing_k(const store::Grid& grid, const SpcBasisOfK& basis_of_k,
                                                std::size_t k_max, const SpcTransformOptions& options,
                                                const SpcTarget& target, const LightingSuite& suite,
                                                SpcTargetReport& target_report, SpcKReport& k_report,
                                                SpcBasis* chosen_basis = nullptr, SpcReport* report = nullptr,
                                                const std::string& source = "");

/// encode_spc_choosing_k for scattered samples (format 4, options.step ignored): judged against `reference`, the grid
/// they resample to exactly (resample_samples(samples, options.rule)); basis_of_k must return bases on the samples'
/// wavelengths.
std::vector<std::uint8_t> encode_spc_samples_choosing_k(const SpcSampleSet& samples, const store::Grid& reference,
                                                        const SpcBasisOfK& basis_of_k, std::size_t k_max,
                                                        const SpcSamplesOptions& options, const SpcTarget& target,
                                                        const LightingSuite& suite, SpcTargetReport& target_report,
                                                        SpcKReport& k_report, SpcBasis* chosen_basis = nullptr,
                                                        SpcReport* report = nullptr, const std::string& source = "");

}  // namespace specula::codec
