#pragma once
// How far apart two spectral BRDF grids are: in value over the grid, and as seen rendered on a sphere.
#include <cstdint>
#include <span>
#include <vector>

#include "specula/codec/environment.h"
#include "specula/store/grid.h"

namespace specula::codec {

struct DiffOptions {
  std::size_t size = 128;  ///< sphere size in pixels for the rendered comparison
};

/// Differences over the cells valid (every band >= 0) in both grids, values times their scale (1/sr); cells
/// valid in one grid only are counted (only_a, only_b) but enter no value metric:
/// rms = sqrt(mean over cells and bands of (a - b)^2); max_abs = max |a - b|;
/// rel_rms_cos = sqrt(sum w (a - b)^2 / sum w a^2) over cells and bands, w = max(0, cos theta_i) max(0, cos theta_o)
/// at the cell centre (brdf::merl_cell_centre), so grazing cells, which a rendering barely shows, weigh little
/// (0 if both sums are 0, infinity if only the reference's is);
/// de00_*: a and b rendered on the same sphere under the same environment (render_spheres), each pixel's XYZ
/// converted to CIELAB with the reference white of that rendering (a white Lambertian facing the viewer under
/// the same light: L* = 100 there, the same for both images, so no separate exposure), CIEDE2000 per sphere
/// pixel; de00_mean the mean, de00_p95 the value of rank ceil(0.95 n) among the n sorted pixel values, de00_max
/// the largest.
struct GridDiff {
  std::uint64_t cells = 0;               ///< valid in both
  std::uint64_t only_a = 0, only_b = 0;  ///< valid in one grid only (not in the value metrics)
  double rms = 0, max_abs = 0, rel_rms_cos = 0;
  double de00_mean = 0, de00_p95 = 0, de00_max = 0;
  SphereRenders renders;    ///< the two renderings compared
  std::vector<float> de00;  ///< per pixel (0 off the sphere)
};

/// CIEDE2000 per pixel of two renderings of one sphere under one light (xyz: 3 floats a pixel), each pixel's XYZ
/// taken to CIELAB with `white`; 0 off the sphere.
struct De00 {
  double mean = 0, p95 = 0, max = 0;  ///< over covered pixels; p95: rank ceil(0.95 n) of the n sorted values
  std::vector<float> per_pixel;
};

/// Compares rendering b with rendering a (same size, same `covered`); UsageError if their sizes differ.
De00 de00_of_renders(std::span<const float> a, std::span<const float> b, std::span<const std::uint8_t> covered,
                     const Eigen::Vector3d& white);

/// Compares a (the reference) with b; InputError if their wavelength grids differ (naming both) or if env gives
/// no white (no light on a surface facing the viewer).
GridDiff diff_grids(const store::Grid& a, const store::Grid& b, const Environment& env,
                    const DiffOptions& options = {});

}  // namespace specula::codec
