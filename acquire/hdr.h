#pragma once
// HDR merge of an exposure series (reference §4.1.1, §5.1): per pixel, the least-squares line of value against
// exposure time over the values inside the camera's linear range; its slope is the radiance estimate (DN/s).
#include <cstdint>
#include <span>
#include <vector>

namespace specula::acquire {

/// Which values count as linear: [low, high] as fractions of full scale (the reference keeps 15-240 of 255).
struct HdrOptions {
  double low = 15.0 / 255;
  double high = 240.0 / 255;
  double min_pearson = 0.99;  ///< a fit with r below this (3 or more points) is flagged non-linear
};

/// Outcome per pixel.
enum class HdrStatus : std::uint8_t {
  ok = 0,          ///< two or more values in range, r >= min_pearson (or exactly two)
  single = 1,      ///< one value in range: that value over its time (no line can be fitted)
  saturated = 2,   ///< no value in range and the shortest exposure above it
  low_signal = 3,  ///< no value in range, all below it: the longest exposure's value over its time
  nonlinear = 4,   ///< Pearson r below min_pearson
};

/// "ok", "single", "saturated", "low_signal" or "nonlinear".
const char* status_name(HdrStatus s);

/// Per pixel: rate (DN/s), status, the fit's Pearson r (1 when fewer than 3 points) and points used.
struct HdrImage {
  std::size_t pixels = 0;
  std::vector<float> rate;
  std::vector<HdrStatus> status;
  std::vector<float> pearson;
  std::vector<std::uint8_t> used;
};

/// Merges `exposures` (one image of `pixels` values each, 0 .. 2^bit_depth - 1) taken at `times` (seconds,
/// positive, any order). UsageError for mismatched sizes, fewer than one exposure, bad options or bit depth.
HdrImage merge_exposures(std::span<const std::span<const std::uint16_t>> exposures, std::span<const double> times,
                         int bit_depth, const HdrOptions& o = {});

}  // namespace specula::acquire
