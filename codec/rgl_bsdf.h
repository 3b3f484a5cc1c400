#pragma once
// An isotropic material in the RGL .bsdf format (Dupuy and Jakob 2018, "An Adaptive Parameterization for Efficient
// Material Acquisition and Rendering"), the fields Mitsuba 3's `measured` plugin and pbrt-v4's MeasuredBxDF read:
// theta_i and phi_i (the incident directions tabulated), ndf and sigma (the microfacet distribution D and its
// projected area, on the unit square u = sqrt(2 theta / pi), v = (phi + pi) / (2 pi)), vndf (the visible normals'
// density per incident direction on that square), luminance (a density on the sample square), and the stored values
// f cos(theta_o) 4 sigma(theta_i) / D(m) at the nodes of the sample square warped by the vndf, per wavelength
// (`wavelengths` + `spectra`) or per RGB channel (`rgb`); jacobian = 1 says the renderer multiplies by D / (4 sigma).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "specula/codec/rgl_tensor.h"

namespace specula::codec {

/// The material, arrays row-major as in the file (last index fastest).
struct RglBsdf {
  std::string description;
  std::vector<float> phi_i = {0.0f};          ///< one value: isotropic (files with more are refused)
  std::vector<float> theta_i;                 ///< ascending, radians
  std::size_t ndf_width = 0, ndf_height = 2;  ///< ndf: ndf_height (v, phi) x ndf_width (u, theta)
  std::vector<float> ndf;
  std::size_t sigma_width = 0, sigma_height = 2;  ///< sigma: the same over the incident direction
  std::vector<float> sigma;
  std::size_t vndf_width = 0, vndf_height = 0;  ///< vndf: theta_i x vndf_height (v, phi) x vndf_width (u, theta)
  std::vector<float> vndf;
  std::size_t resolution = 0;      ///< the sample square's nodes per side
  std::vector<float> luminance;    ///< theta_i x resolution x resolution
  bool rgb = false;                ///< `rgb` field instead of `wavelengths` + `spectra`
  std::vector<float> wavelengths;  ///< nm, ascending (spectral files only)
  std::vector<float> values;       ///< theta_i x channels x resolution x resolution (channels: wavelengths or 3)
  bool jacobian = true;
  std::vector<std::uint8_t>
      valid;  ///< bits, most significant first, of theta_i x resolution x resolution: wo above the horizon
  std::vector<std::uint32_t> version = {1, 0};

  std::size_t channels() const { return rgb ? 3 : wavelengths.size(); }
};

/// The tensor fields of `bsdf` in the order of the published files; UsageError if the arrays' sizes disagree.
TensorFile to_tensor(const RglBsdf& bsdf);
/// The material in `file`, checked as the renderers check it (every field present with its rank, type and matching
/// extents) and further: isotropic (one phi_i), theta_i ascending in [0, pi/2], wavelengths ascending and positive,
/// every value finite, ndf and sigma non-negative, vndf and luminance non-negative and not zero everywhere for an
/// incident direction; InputError naming `label`, the field and the fix.
RglBsdf from_tensor(const TensorFile& file, const std::string& label);
/// read_tensor_file + from_tensor.
RglBsdf read_rgl_bsdf(const std::filesystem::path& path);
/// Writes `bsdf` through a temporary renamed over `path` when complete.
void write_rgl_bsdf(const std::filesystem::path& path, const RglBsdf& bsdf);

}  // namespace specula::codec
