#include "specula/acquire/synth_samples.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {

void evaluate_noisy(const brdf::SpectralModel& model, std::span<const double> angles, std::span<float> values,
                    double noise, std::uint64_t seed, std::uint64_t batch) {
  if (!(noise >= 0 && noise <= 1))
    throw UsageError("evaluate_noisy: noise must be a relative standard deviation from 0 to 1, got " +
                     std::to_string(noise));
  const std::size_t b = model.bands();
  if (angles.size() % 4 != 0 || values.size() != angles.size() / 4 * b)
    throw UsageError("evaluate_noisy: needs n x 4 angles and n x " + std::to_string(b) + " values, got " +
                     std::to_string(angles.size()) + " angles and " + std::to_string(values.size()) + " values");
  const std::size_t n = angles.size() / 4, pieces = (n + kNoisePiece - 1) / kNoisePiece;
  // The models are read-only; each piece writes its own values and draws from its own generator.
  parallel_for(pieces, [&](std::size_t p) {
    const std::size_t first = p * kNoisePiece, count = std::min(kNoisePiece, n - first);
    const auto v = values.subspan(b * first, b * count);
    brdf::evaluate_at(model, angles.subspan(4 * first, 4 * count), v);
    if (noise > 0) {
      std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull ^ (batch << 24) ^ std::uint64_t(p));
      std::normal_distribution<float> g(0.0f, float(noise));
      for (float& x : v) x *= 1 + g(rng);
    }
  });
}

void random_configurations(std::size_t n, std::uint64_t seed, std::uint64_t block, std::vector<double>& angles) {
  using std::numbers::pi;
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + block);
  std::uniform_real_distribution<double> u(0, 1);
  angles.resize(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    angles[4 * i] = std::acos(u(rng));
    angles[4 * i + 1] = 2 * pi * u(rng) - pi;
    angles[4 * i + 2] = std::acos(u(rng));
    angles[4 * i + 3] = 2 * pi * u(rng) - pi;
  }
}

std::size_t thin_evenly(std::vector<double>& angles, std::size_t& seen, std::size_t count, std::size_t total) {
  if (angles.size() % 4 != 0) throw UsageError("thin_evenly: angles must hold n x 4 values");
  if (count == 0 || count >= total) throw UsageError("thin_evenly: count must be from 1 to total - 1");
  const std::size_t n = angles.size() / 4;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n; ++i, ++seen)
    if ((seen + 1) * count / total > seen * count / total)
      std::copy_n(angles.begin() + std::ptrdiff_t(4 * i), 4, angles.begin() + std::ptrdiff_t(4 * kept++));
  angles.resize(4 * kept);
  return kept;
}

SynthesisCount synthesize_samples(const brdf::SpectralModel& model, const SampleSynthesis& o,
                                  const std::function<void(std::span<const double>, std::span<const float>)>& sink) {
  const std::size_t b = model.bands();
  std::vector<double> angles;
  std::vector<float> values;
  SynthesisCount out;
  if (o.geometry == SampleSynthesis::Geometry::scan) {
    const std::vector<ScanPixel> px = scan_pixels(o.rig);
    out.pixels = px.size();
    // With a count, every lit sample is counted first and the scan thinned evenly to it.
    std::size_t total = 0;
    if (o.count) {
      for (std::size_t j = 0; j < o.rig.lights; ++j) {
        angles.clear();
        total += scan_light(o.rig, px, j, angles);
      }
    }
    Progress progress("synth-samples", o.rig.lights);
    std::size_t seen = 0;
    for (std::size_t j = 0; j < o.rig.lights; ++j) {
      check_interrupt();
      angles.clear();
      scan_light(o.rig, px, j, angles);
      if (o.count && o.count < total) thin_evenly(angles, seen, o.count, total);
      values.resize(angles.size() / 4 * b);
      evaluate_noisy(model, angles, values, o.noise, o.seed, j);
      sink(angles, values);
      out.samples += angles.size() / 4;
      progress.advance();
    }
    return out;
  }
  const std::size_t block = std::size_t(1) << 20;
  Progress progress("synth-samples", o.count);
  for (std::size_t first = 0; first < o.count; first += block) {
    check_interrupt();
    const std::size_t n = std::min(block, o.count - first);
    random_configurations(n, o.seed, first / block, angles);
    values.resize(n * b);
    evaluate_noisy(model, angles, values, o.noise, o.seed, first / block);
    sink(angles, values);
    out.samples += n;
    progress.advance(n);
  }
  return out;
}

}  // namespace specula::acquire
