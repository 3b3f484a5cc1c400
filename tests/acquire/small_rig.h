#pragma once
// A small simulated rig for the acquisition tests: a square sensor, the sphere off axis by 5 % and 2 % of its
// image diameter (as simulate-capture places it), lights on the arc from 10 degrees.
#include <vector>

#include "specula/acquire/simulate.h"

namespace specula::test {

/// The LCTF's default bands: 420 to 720 nm every 10.
inline std::vector<double> bands_420_720() {
  std::vector<double> b;
  for (int l = 420; l <= 720; l += 10) b.push_back(l);
  return b;
}

inline acquire::SimulatorOptions small_rig(int size, double sphere_px, std::size_t lights, double step_deg,
                                           std::vector<double> bands, bool noise) {
  acquire::SimulatorOptions o;
  o.width = o.height = size;
  o.rig.sphere_px = sphere_px;
  o.rig.off_axis = 0.05 * sphere_px / o.rig.focal_px * o.rig.distance;
  o.rig.off_axis_y = 0.02 * sphere_px / o.rig.focal_px * o.rig.distance;
  o.rig.lights = lights;
  o.rig.light_step_deg = step_deg;
  o.bands = std::move(bands);
  o.noise = noise;
  return o;
}

}  // namespace specula::test
