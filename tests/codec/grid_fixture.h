#pragma once
// The codec tests' analytic grids: a model evaluated at every MERL cell, on 7 bands to keep the tests fast.
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "specula/store/store.h"

namespace specula::test {

inline const WavelengthGrid kCodecBands = WavelengthGrid::range(420, 720, 50);

/// `model` at every cell of the MERL grid (bands x cells).
inline store::Grid grid_of(const brdf::SpectralModel& model) {
  store::Grid g;
  g.wavelengths = model.wavelengths();
  g.brdf.resize(model.bands() * brdf::kMerlCells);
  brdf::evaluate_grid(model, g.brdf);
  return g;
}

}  // namespace specula::test
