#include "specula/acquire/scan_holdout.h"

#include <algorithm>
#include <cmath>

#include "specula/acquire/prior_resample.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {

KeptSamples::KeptSamples(const brdf::SampleSource& src, std::span<const std::uint8_t> held) : src_(src) {
  for (std::size_t s = 0; s < held.size(); ++s)
    if (!held[s]) kept_.push_back(std::uint32_t(s));
}

void KeptSamples::read_angles(std::size_t first, std::size_t count, std::span<double> out) const {
  gather<double>(first, count, 4, out,
                 [&](std::size_t a, std::size_t n, std::span<double> to) { src_.read_angles(a, n, to); });
}

void KeptSamples::read_values(std::size_t first, std::size_t count, std::span<float> out) const {
  gather<float>(first, count, bands(), out,
                [&](std::size_t a, std::size_t n, std::span<float> to) { src_.read_values(a, n, to); });
}

void KeptSamples::read_variance(std::size_t first, std::size_t count, std::span<float> out) const {
  gather<float>(first, count, bands(), out,
                [&](std::size_t a, std::size_t n, std::span<float> to) { src_.read_variance(a, n, to); });
}

// Rows [first, first + count) of the kept samples, width values each, read in the source's blocks that hold them: a
// sparse selection reads neither the rows between its blocks nor more than a block at once.
template <class T, class Read>
void KeptSamples::gather(std::size_t first, std::size_t count, std::size_t width, std::span<T> out,
                         const Read& read) const {
  if (first + count > kept_.size() || out.size() != count * width)
    throw UsageError("holdout: kept samples out of range");
  const std::size_t block = std::max<std::size_t>(1, src_.block_rows());
  Buffer<T> buf;  // left unwritten until read into
  for (std::size_t i = 0; i < count;) {
    const std::size_t lo = kept_[first + i];
    std::size_t j = i + 1;
    while (j < count && kept_[first + j] < lo + block) ++j;
    const std::size_t hi = std::size_t(kept_[first + j - 1]) + 1;
    buf.resize((hi - lo) * width);
    read(lo, hi - lo, buf);
    for (; i < j; ++i)
      std::copy_n(buf.begin() + std::ptrdiff_t((kept_[first + i] - lo) * width), width,
                  out.begin() + std::ptrdiff_t(i * width));
  }
}

std::vector<std::int32_t> sample_slots(const brdf::SampleSource& src, std::span<std::uint8_t> theta_d_rows) {
  const std::size_t n = src.size(), block = std::max<std::size_t>(1, src.block_rows());
  if (!theta_d_rows.empty() && theta_d_rows.size() != n)
    throw UsageError("holdout: give one theta_d row slot per sample, or none");
  std::vector<std::int32_t> slots(n);
  std::vector<double> angles;
  Progress progress("sample cells", n);
  for (std::size_t first = 0; first < n; first += block) {
    check_interrupt();
    const std::size_t count = std::min(block, n - first);
    angles.resize(4 * count);
    src.read_angles(first, count, angles);
    valid_slots(angles, std::span(slots).subspan(first, count),
                theta_d_rows.empty() ? theta_d_rows : theta_d_rows.subspan(first, count));
    progress.advance(count);
  }
  return slots;
}

double blend_error(const PriorObservations& obs, std::size_t o, std::size_t cell, double cc, double c,
                   std::span<const float> fitted, std::span<const float> kd, std::size_t b, double eps, bool log) {
  double sum = 0;
  for (std::size_t k = 0; k < b; ++k) {
    const std::size_t at = k * brdf::kMerlCells + cell;
    const double blend = mix_estimates(kd[at], fitted[at], c, cc, eps, log);
    const double d = std::log((blend * cc + eps) / (double(obs.values[o * b + k]) * cc + eps));
    sum += d * d;
  }
  return sum / double(b);
}

double judge_epsilon(const PriorObservations& obs, const BrdfPrior& prior, std::size_t b) {
  const auto& cosines = valid_cell_cosines();
  std::vector<double> value(obs.cell.size()), reference(obs.cell.size());
  for (std::size_t o = 0; o < obs.cell.size(); ++o) {
    double sum = 0;
    for (std::size_t k = 0; k < b; ++k) sum += obs.values[o * b + k];
    value[o] = sum / double(b) * cosines[obs.cell[o]];
    reference[o] = prior.reference[obs.cell[o]];
  }
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  if (value.empty()) return prior.epsilon;
  const double ref = median(reference);
  return ref > 0 ? prior.epsilon * std::clamp(median(value) / ref, 1e-6, 1.0) : prior.epsilon;
}

std::vector<double> blend_error_table(const PriorObservations& obs, std::span<const float> fitted,
                                      std::span<const float> kd, std::size_t b, std::size_t m, double eps, bool log,
                                      const std::function<double(std::size_t cell, std::size_t l)>& weight) {
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  std::vector<double> err(obs.cell.size() * m, 0.0);
  parallel_for(
      obs.cell.size(),
      [&](std::size_t o) {
        const std::size_t cell = cells[obs.cell[o]];
        const double cc = cosines[obs.cell[o]];
        const bool local = kd[cell] >= 0;
        for (std::size_t l = 0; l < m; ++l)
          err[o * m + l] = blend_error(obs, o, cell, cc, local ? weight(cell, l) : 0.0, fitted, kd, b, eps, log);
      },
      1024);
  return err;
}

std::vector<double> weight_error_table(const PriorObservations& obs, std::span<const float> fitted,
                                       std::span<const float> kd, std::size_t b, std::span<const double> ladder,
                                       double eps, bool log) {
  return blend_error_table(obs, fitted, kd, b, ladder.size(), eps, log,
                           [&](std::size_t, std::size_t l) { return ladder[l]; });
}

std::vector<double> weight_errors(const PriorObservations& obs, std::span<const float> fitted,
                                  std::span<const float> kd, std::size_t b, std::span<const double> ladder, double eps,
                                  bool log) {
  const std::vector<double> err = weight_error_table(obs, fitted, kd, b, ladder, eps, log);
  const std::size_t m = ladder.size();
  std::vector<double> mean(m, 0.0);
  for (std::size_t o = 0; o < obs.cell.size(); ++o)
    for (std::size_t l = 0; l < m; ++l) mean[l] += err[o * m + l];
  for (double& x : mean) x = obs.cell.empty() ? 0.0 : x / double(obs.cell.size());
  return mean;
}

std::size_t least(const std::vector<double>& v) {
  return std::size_t(std::min_element(v.begin(), v.end()) - v.begin());
}

}  // namespace specula::acquire
