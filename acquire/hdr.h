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
  double longest_time = 0;  ///< the longest exposure (s): a low_signal pixel's value is rate x this time
};

/// The camera's noise (the simulator's sensor, acquire/simulate.h): each value is bias + rate t + Gaussian noise of
/// variance read_noise_dn^2 + rate t / electrons_per_dn (shot noise: Poisson in electrons), rounded to an integer.
struct SensorNoise {
  double read_noise_dn = 1.5;
  double electrons_per_dn = 4;
  double dark_dn = 8;  ///< the bias every value carries
};

/// Variance ((DN/s)^2) of merge_exposures' rate for a pixel of true rate `rate` (DN/s above the bias) over `times`:
/// each value's variance read^2 + rate t / gain + 1/12 (rounding), the values inside the linear range combined as
/// the least-squares slope combines them (sum (t - mean t)^2 var / (sum (t - mean t)^2)^2); one value, or none
/// (low signal: the longest exposure; saturated: the shortest), its variance over its time squared. UsageError for
/// bad times, bit depth, options or noise.
double hdr_rate_variance(double rate, std::span<const double> times, int bit_depth, const SensorNoise& noise,
                         const HdrOptions& o = {});

/// hdr_rate_variance for many pixels of one exposure series: the times checked and sorted once.
class RateVariance {
 public:
  /// UsageError for bad times, bit depth, options or noise (as hdr_rate_variance).
  RateVariance(std::span<const double> times, int bit_depth, const SensorNoise& noise, const HdrOptions& o = {});
  /// hdr_rate_variance(max(rate, 0), ...) without allocating.
  double operator()(double rate) const;

 private:
  std::vector<double> sorted_;
  double lo_ = 0, hi_ = 0;
  SensorNoise noise_;
};

/// Merges `exposures` (one image of `pixels` values each, 0 .. 2^bit_depth - 1) taken at `times` (seconds,
/// positive, any order). UsageError for mismatched sizes, fewer than one exposure, bad options or bit depth.
HdrImage merge_exposures(std::span<const std::span<const std::uint16_t>> exposures, std::span<const double> times,
                         int bit_depth, const HdrOptions& o = {});

}  // namespace specula::acquire
