#pragma once
// A BRDF on the MERL grid in memory: what codec/ and acquire/ pass around, without the store (or HDF5) behind it.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/cube.h"

namespace specula::store {

/// The parameterisation of the RGL .bsdf file a grid was imported from (codec/rgl_bsdf.h: Dupuy and Jakob 2018): the
/// nodes an export needs to tabulate the grid where its source tabulated it. Arrays row-major as in the file.
struct GridParameterisation {
  std::vector<float> phi_i, theta_i;          ///< radians; phi_i has one value (isotropic)
  std::size_t ndf_width = 0, ndf_height = 0;  ///< ndf: height (phi) x width (theta)
  std::vector<float> ndf;
  std::size_t sigma_width = 0, sigma_height = 0;  ///< sigma: height x width
  std::vector<float> sigma;
  std::size_t vndf_width = 0, vndf_height = 0;  ///< vndf: phi_i x theta_i x height x width
  std::vector<float> vndf;
  std::size_t resolution = 0;  ///< the sample square's nodes per side
  std::string description;     ///< the source file's description

  bool operator==(const GridParameterisation&) const = default;
};

/// A B-band BRDF in the MERL half/difference layout: brdf is bands x 90 x 90 x 180 float32 (band slowest,
/// phi_d fastest, the cell order of core/brdf_geometry.h); a negative value means no data; value * scale is in 1/sr.
struct Grid {
  WavelengthGrid wavelengths;
  double scale = 1.0;
  std::vector<float> brdf;
  std::string units = "1/sr";
  Provenance provenance;
  /// Kept from an imported RGL file (absent for grids made otherwise, or that lost it, e.g. through a .spgrid).
  std::optional<GridParameterisation> parameterisation;

  std::size_t bands() const { return wavelengths.size(); }
};

}  // namespace specula::store
