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

HdrImage merge_exposures(std::span<const std::span<const std::uint16_t>> exposures, std::span<const double> times,
                         int bit_depth, const HdrOptions& o) {
  if (exposures.empty() || exposures.size() != times.size())
    throw UsageError("HDR merge: give one exposure time per image, at least one image");
  if (bit_depth < 8 || bit_depth > 16) throw UsageError("HDR merge: bit depth must be 8 to 16");
  if (!(o.low >= 0 && o.low < o.high && o.high <= 1) || !(o.min_pearson >= -1 && o.min_pearson <= 1))
    throw UsageError("HDR merge: the linear range must satisfy 0 <= low < high <= 1, and min_pearson lie in [-1, 1]");
  const std::size_t n = exposures.front().size();
  for (std::size_t e = 0; e < exposures.size(); ++e) {
    if (exposures[e].size() != n) throw UsageError("HDR merge: every exposure must have the same number of pixels");
    if (!(times[e] > 0) || !std::isfinite(times[e])) throw UsageError("HDR merge: exposure times must be positive");
  }
  const double full = double((1 << bit_depth) - 1), lo = o.low * full, hi = o.high * full;
  std::vector<std::size_t> order(times.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return times[a] < times[b]; });
  HdrImage out;
  out.pixels = n;
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
