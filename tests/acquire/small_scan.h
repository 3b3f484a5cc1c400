#pragma once
// A small scan for the resampling tests: the reference's rig shrunk to a 100-pixel sphere and 40 lights 4 degrees
// apart (about 0.3 M samples), its values a model's, optionally with multiplicative Gaussian noise.
#include <random>
#include <vector>

#include "specula/acquire/scan.h"
#include "specula/core/brdf_models.h"

namespace specula::test {

struct SmallScan {
  std::vector<double> angles;  ///< n x 4, radians
  std::vector<float> values;   ///< n x bands
};

/// m seen by the small rig; each value times 1 + N(0, noise) drawn from a generator seeded by seed (none at 0).
inline SmallScan small_rig_scan(const brdf::SpectralModel& m, double noise = 0, unsigned seed = 0) {
  const acquire::ScanRig rig{.sphere_px = 100, .light_step_deg = 4, .lights = 40};
  const auto pixels = acquire::scan_pixels(rig);
  SmallScan s;
  for (std::size_t j = 0; j < rig.lights; ++j) acquire::scan_light(rig, pixels, j, s.angles);
  s.values.resize(s.angles.size() / 4 * m.bands());
  brdf::evaluate_at(m, s.angles, s.values);
  if (noise > 0) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0, noise);
    for (float& v : s.values) v = float(v * (1 + n(rng)));
  }
  return s;
}

}  // namespace specula::test
