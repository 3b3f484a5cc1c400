#pragma once
// Spectral lighting for judging BRDFs by eye: a latitude-longitude environment plus an optional sun, and a
// sphere rendered under it from a spectral grid. World frame as codec/render.h: the viewer looks along -z,
// image x to the right, y up. Lat-long row 0 looks up (+y); the polar angle theta runs from +y, the azimuth
// phi around +y from +z towards +x: d = (sin theta sin phi, cos theta, sin theta cos phi).
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/wavelengths.h"
#include "store/store.h"

namespace specula::codec {

struct Environment {
  WavelengthGrid wavelengths;
  std::size_t width = 0, height = 0;
  std::vector<float> radiance;         ///< height x width x bands, relative spectral radiance
  Eigen::Vector3d sun_direction{0, 1, 0};
  Eigen::VectorXd sun_irradiance;      ///< bands values at normal incidence; empty: no sun
  std::string description;
};

/// The built-in environment on `grid`: a CIE daylight sky of 12000 K brightening towards the zenith, a green-brown
/// ground lit by daylight, and a 5500 K daylight sun at (-0.45, 0.6, 0.66) carrying most of the irradiance.
Environment default_environment(const WavelengthGrid& grid);
/// A lat-long OpenEXR: spectral (Fichet et al. 2021 channels, interpolated onto `grid`) or RGB (linear sRGB
/// primaries, each pixel uplifted by Appendix A's non-negative least squares as emission with an equal-energy
/// white); negative or non-finite pixels are an InputError naming the file.
Environment read_environment(const std::filesystem::path& path, const WavelengthGrid& grid);

/// Spheres rendered under one environment: per grid, per pixel XYZ (3 floats, rows top to bottom), which pixels
/// show the sphere, and the XYZ of a white Lambertian surface facing the viewer under the same light.
struct SphereRenders {
  std::size_t size = 0;
  std::vector<std::vector<float>> xyz;
  std::vector<std::uint8_t> covered;
  Eigen::Vector3d white = Eigen::Vector3d::Zero();
};

/// Renders each grid on a size x size sphere under `env`: L = sum over the environment (averaged to 32 x 16
/// directions) of f L_env cos(theta_i) d_omega, plus f E_sun cos(theta_sun); f looked up from the grid's cell as
/// MERL's BRDFRead.cpp does (no data counts as 0), value * scale. Grids must share env's wavelengths (InputError).
SphereRenders render_spheres(const std::vector<const store::Grid*>& grids, const Environment& env, std::size_t size);

}  // namespace specula::codec
