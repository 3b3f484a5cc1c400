#include "specula/acquire/hdr.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {

const char* status_name(HdrStatus s) {
  static constexpr const char* names[] = {"ok", "single", "saturated", "low_signal", "nonlinear"};
  return names[std::size_t(s)];
}

namespace {

// The checks merge_exposures and hdr_rate_variance share; the exposures' order, shortest first.
std::vector<std::size_t> checked_order(std::span<const double> times, int bit_depth, const HdrOptions& o) {
  if (times.empty()) throw UsageError("HDR merge: give one exposure time per image, at least one image");
  if (bit_depth < 8 || bit_depth > 16) throw UsageError("HDR merge: bit depth must be 8 to 16");
  if (!(o.low >= 0 && o.low < o.high && o.high <= 1) || !(o.min_pearson >= -1 && o.min_pearson <= 1))
    throw UsageError("HDR merge: the linear range must satisfy 0 <= low < high <= 1, and min_pearson lie in [-1, 1]");
  for (const double t : times)
    if (!(t > 0) || !std::isfinite(t)) throw UsageError("HDR merge: exposure times must be positive");
  std::vector<std::size_t> order(times.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return times[a] < times[b]; });
  return order;
}

}  // namespace

RateVariance::RateVariance(std::span<const double> times, int bit_depth, const SensorNoise& noise, const HdrOptions& o)
    : noise_(noise) {
  for (const std::size_t e : checked_order(times, bit_depth, o)) sorted_.push_back(times[e]);
  if (!(noise.read_noise_dn >= 0) || !(noise.electrons_per_dn > 0) || !(noise.dark_dn >= 0))
    throw UsageError("HDR noise: the rate and read noise must be >= 0, the gain positive, the bias >= 0");
  const double full = double((1 << bit_depth) - 1);
  lo_ = o.low * full;
  hi_ = o.high * full;
}

double RateVariance::operator()(double rate) const {
  rate = std::max(rate, 0.0);
  auto variance = [&](double t) {
    return noise_.read_noise_dn * noise_.read_noise_dn + rate * t / noise_.electrons_per_dn + 1.0 / 12;
  };
  // The values grow with the time: the ones in range are a run of the sorted times.
  std::size_t first = sorted_.size(), used = 0;
  double mean = 0;
  for (std::size_t e = 0; e < sorted_.size(); ++e)
    if (const double v = noise_.dark_dn + rate * sorted_[e]; v >= lo_ && v <= hi_) {
      first = std::min(first, e);
      ++used;
      mean += sorted_[e];
    }
  if (used == 0) {
    const double t = noise_.dark_dn + rate * sorted_.front() > hi_ ? sorted_.front() : sorted_.back();
    return variance(t) / (t * t);
  }
  if (used == 1) return variance(sorted_[first]) / (sorted_[first] * sorted_[first]);
  mean /= double(used);
  double stt = 0, sum = 0;
  for (std::size_t e = first; e < first + used; ++e) {
    const double d = sorted_[e] - mean;
    stt += d * d;
    sum += d * d * variance(sorted_[e]);
  }
  if (!(stt > 0)) return variance(sorted_[first]) / (sorted_[first] * sorted_[first] * double(used));
  return sum / (stt * stt);
}

double hdr_rate_variance(double rate, std::span<const double> times, int bit_depth, const SensorNoise& noise,
                         const HdrOptions& o) {
  if (!(rate >= 0) || !std::isfinite(rate))
    throw UsageError("HDR noise: the rate and read noise must be >= 0, the gain positive, the bias >= 0");
  return RateVariance(times, bit_depth, noise, o)(rate);
}

HdrImage merge_exposures(std::span<const std::span<const std::uint16_t>> exposures, std::span<const double> times,
                         int bit_depth, const HdrOptions& o) {
  if (exposures.size() != times.size())
    throw UsageError("HDR merge: give one exposure time per image, at least one image");
  const std::vector<std::size_t> order = checked_order(times, bit_depth, o);
  const std::size_t n = exposures.front().size();
  for (std::size_t e = 0; e < exposures.size(); ++e)
    if (exposures[e].size() != n) throw UsageError("HDR merge: every exposure must have the same number of pixels");
  const double full = double((1 << bit_depth) - 1), lo = o.low * full, hi = o.high * full;
  HdrImage out;
  out.pixels = n;
  out.longest_time = times[order.back()];
  out.rate.assign(n, 0.0f);
  out.status.assign(n, HdrStatus::ok);
  out.pearson.assign(n, 1.0f);
  out.used.assign(n, 0);
  parallel_for(
      n,
      [&](std::size_t p) {
        double st = 0, sv = 0, stt = 0, svv = 0, stv = 0;
        int k = 0;
        for (const std::size_t e : order) {
          const double v = exposures[e][p];
          if (v < lo || v > hi) continue;
          const double t = times[e];
          st += t, sv += v, stt += t * t, svv += v * v, stv += t * v;
          ++k;
        }
        out.used[p] = std::uint8_t(std::min(k, 255));
        if (k >= 2) {
          const double ctt = stt - st * st / k, cvv = svv - sv * sv / k, ctv = stv - st * sv / k;
          out.rate[p] = ctt > 0 ? float(ctv / ctt) : 0.0f;
          if (k >= 3) {
            const double r = ctt > 0 && cvv > 0 ? ctv / std::sqrt(ctt * cvv) : 0.0;
            out.pearson[p] = float(r);
            if (r < o.min_pearson) out.status[p] = HdrStatus::nonlinear;
          }
        } else if (k == 1) {
          out.rate[p] = float(sv / st);
          out.status[p] = HdrStatus::single;
        } else if (double(exposures[order.front()][p]) > hi) {
          out.status[p] = HdrStatus::saturated;
        } else {
          const std::size_t e = order.back();
          out.rate[p] = float(double(exposures[e][p]) / times[e]);
          out.status[p] = HdrStatus::low_signal;
        }
      },
      4096);
  return out;
}

}  // namespace specula::acquire
