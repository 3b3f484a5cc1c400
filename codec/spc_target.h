#pragma once
// Coding a grid to a perceptual target: the coarsest format-2 step whose decoding the lighting suite
// (codec/suite.h) cannot tell from the grid beyond the target.
#include <cstdint>
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

}  // namespace specula::codec
