#pragma once
// Scattered spectral BRDF samples in pbrt-v2's irregular text format (the Cornell measurements): '#'
// comments, the number of wavelengths, the wavelengths (nm), then per sample theta_i phi_i theta_o phi_o
// (radians) followed by one value per wavelength.
#include <filesystem>
#include <vector>

#include "specula/core/wavelengths.h"

namespace specula::store {

struct IrregularBrdf {
  WavelengthGrid wavelengths;
  std::vector<double> angles;  ///< n x 4: theta_i, phi_i, theta_o, phi_o
  std::vector<float> values;   ///< n x bands
  std::size_t size() const { return angles.size() / 4; }
};

/// Parses a .brdf file; throws InputError naming the file, the line and the rule for anything else (a
/// truncated sample, a non-number, NaN, a polar angle outside [0, pi/2], a negative value).
IrregularBrdf read_brdf_irregular(const std::filesystem::path& path);

}  // namespace specula::store
