#pragma once
// A BRDF on the MERL grid in memory: what codec/ and acquire/ pass around, without the store (or HDF5) behind it.
#include <cstddef>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/cube.h"

namespace specula::store {

/// A B-band BRDF in the MERL half/difference layout: brdf is bands x 90 x 90 x 180 float32 (band slowest,
/// phi_d fastest, the cell order of core/brdf_geometry.h); a negative value means no data; value * scale is in 1/sr.
struct Grid {
  WavelengthGrid wavelengths;
  double scale = 1.0;
  std::vector<float> brdf;
  std::string units = "1/sr";
  Provenance provenance;

  std::size_t bands() const { return wavelengths.size(); }
};

}  // namespace specula::store
