#pragma once
// Spectral lighting for judging BRDFs by eye: a latitude-longitude environment plus an optional sun, and a
// sphere rendered under it from a spectral grid. World frame as codec/render.h: the viewer looks along -z,
// image x to the right, y up. Pixel (x, y) of a W x H lat-long map covers the polar angle theta in
// [y, y + 1] pi / H, measured from +y (row 0 looks up), and the azimuth phi in [x, x + 1] 2 pi / W, measured
// around +y from +z (towards the viewer) through +x: d = (sin theta sin phi, cos theta, sin theta cos phi).
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/codec/spc_eval.h"
#include "specula/core/wavelengths.h"
#include "specula/store/grid.h"

namespace specula::codec {

struct Environment {
  WavelengthGrid wavelengths;
  std::size_t width = 0, height = 0;
  std::vector<float> radiance;  ///< height x width x bands, spectral radiance (relative units)
  Eigen::Vector3d sun_direction{0, 1, 0};
  Eigen::VectorXd sun_irradiance;  ///< bands values at normal incidence; empty: no sun
  std::string description;
};

/// The renderer's direction set: an environment is integrated over at most this many regions (fewer for a
/// smaller map), each a block of whole map pixels.
inline constexpr std::size_t kEnvironmentRegionsW = 64, kEnvironmentRegionsH = 32;

/// An environment as point lights (what render_spheres integrates): each region of a regions_w x regions_h split
/// of the map (fewer for a smaller map) with any power becomes a light along its mean vector m (the solid-angle
/// average of its directions), `length` |m| and `power` the integral of L over it (band-major:
/// power[b * count + j]); the sun, if any, is one more light with length 1.
struct EnvironmentLights {
  std::size_t count = 0;
  std::vector<Eigen::Vector3d> dir;  ///< unit, world frame
  std::vector<double> length;
  std::vector<double> power;
};
/// The lights of `env` split into at most regions_w x regions_h regions (each >= 1, else UsageError).
EnvironmentLights environment_lights(const Environment& env, std::size_t regions_w, std::size_t regions_h);

/// The built-in environment on `grid`: a CIE daylight sky of 12000 K brightening towards the zenith, a green-brown
/// ground lit by daylight, and a 5500 K daylight sun at (-0.45, 0.6, 0.66) carrying most of the irradiance.
Environment default_environment(const WavelengthGrid& grid);
/// Radiance `radiance` (one value per band of `grid`, finite, >= 0, else UsageError) from every direction, no sun.
Environment uniform_environment(const WavelengthGrid& grid, const Eigen::VectorXd& radiance);
/// A lat-long OpenEXR: spectral (Fichet et al. 2021 emissive S0.* channels, interpolated onto `grid`; the map
/// kept as is) or RGB (linear sRGB primaries; every pixel uplifted by Appendix A's non-negative least squares
/// as emission with an equal-energy white, then box-filtered with exact solid-angle weights by the smallest
/// factor dividing both sides that leaves at most 256 x 128 pixels). InputError naming the file for negative or
/// non-finite values, reflectance (T.*) channels, or wavelengths not covering `grid`.
Environment read_environment(const std::filesystem::path& path, const WavelengthGrid& grid);

/// Spheres rendered under one environment: per grid, per pixel XYZ (3 floats, rows top to bottom), which pixels
/// show the sphere, and the XYZ of a white Lambertian surface facing the viewer under the same light.
struct SphereRenders {
  std::size_t size = 0;
  std::vector<std::vector<float>> xyz;
  std::vector<std::uint8_t> covered;
  Eigen::Vector3d white = Eigen::Vector3d::Zero();
};

/// Renders each grid on a size x size sphere (8 to 4096, else UsageError) under `env`, one sample at each pixel
/// centre (normal n, viewer +z): L = sum over regions j of f(d_j, wo) P_j (n . m_j) + f(sun, wo) E_sun (n . sun),
/// over lights with n . d > 0, where region j (see kEnvironmentRegionsW) has power P_j = integral of L_env
/// d_omega, mean vector m_j = (integral of d d_omega) / (its solid angle), direction d_j = m_j / |m_j|; f looked
/// up in the grid's cell as MERL's BRDFRead.cpp does (of the directions rounded to float, merl_indices) (no data counts
/// as 0), value * scale; XYZ by the CIE 1931 2 degree CMFs. Deterministic and independent of the thread count. Grids
/// must share env's wavelengths (InputError).
SphereRenders render_spheres(const std::vector<const store::Grid*>& grids, const Environment& env, std::size_t size);
/// As above for coded BRDFs evaluated from their coefficients (SpcBrdf::evaluate_cell in the same cells), without
/// a grid: equal to rendering their expand_spc grids to float precision.
SphereRenders render_spheres(std::span<const SpcBrdf* const> brdfs, const Environment& env, std::size_t size);

}  // namespace specula::codec
