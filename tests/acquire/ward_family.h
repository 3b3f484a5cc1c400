#pragma once
// Five-band Ward materials for the prior's tests: a diffuse colour ramp from blue to red, a neutral specular lobe.
#include <Eigen/Core>

#include "specula/core/brdf_models.h"
#include "specula/core/wavelengths.h"

namespace specula::test {

inline const WavelengthGrid kWardBands = WavelengthGrid::range(400, 700, 75);  // 5 bands keep the grids small

/// A Ward material on kWardBands: diffuse albedo rising linearly from `blue` (400 nm) to `red` (700 nm), specular
/// albedo rho_s and roughness alpha in every band.
inline brdf::Ward ward(double red, double blue, double rho_s, double alpha) {
  Eigen::VectorXd rd(5), rs = Eigen::VectorXd::Constant(5, rho_s), a = Eigen::VectorXd::Constant(5, alpha);
  for (int i = 0; i < 5; ++i) rd[i] = blue + (red - blue) * i / 4.0;
  return brdf::Ward(kWardBands, rd, rs, a);
}

}  // namespace specula::test
