#pragma once
// A quick look at a BRDF: a unit sphere seen orthographically along -z (image rows top to bottom), lit by one
// directional light, in linear sRGB.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "specula/codec/merl.h"
#include "specula/codec/spc_eval.h"

namespace specula::store {
struct Grid;
}  // namespace specula::store

namespace specula::codec {

struct SphereRenders;

/// A square rendering: linear RGB (3 per pixel, row-major) and which pixels show the sphere.
struct SphereImage {
  std::size_t size = 0;
  std::vector<float> linear;
  std::vector<std::uint8_t> covered;
};

/// Renders `brdf` on a sphere of size x size pixels: each pixel centre inside the disc has normal
/// n = (x, y, sqrt(1 - x^2 - y^2)), the viewer is at +z and the light of irradiance pi (so a white Lambertian
/// surface facing it is 1) comes from direction `light` (world, normalised here); pixel value
/// pi * f(wi, wo) * cos(theta_i) with f looked up as BRDFRead.cpp does (no data counts as 0).
/// Throws UsageError for size 0 or a zero light direction.
SphereImage render_sphere(const MerlBrdf& brdf, std::size_t size, const Eigen::Vector3d& light);
/// As above for a coded BRDF evaluated in the same cells, its spectrum taken to RGB by `weights` (3 x B, e.g.
/// rgb_weights(); else UsageError) with negative channels set to 0: render_sphere(grid_to_merl(expand_spc(...),
/// weights).brdf, ...) to float precision, without the grid.
SphereImage render_sphere(const SpcBrdf& brdf, const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights,
                          std::size_t size, const Eigen::Vector3d& light);
/// As above for a spectral grid seen under `illuminant` (its SPD on the grid's wavelengths): the grid taken to RGB
/// through the CIE 1931 CMFs under that light (grid_to_merl with rgb_weights) and rendered as a MERL BRDF.
SphereImage render_sphere(const store::Grid& grid, const Eigen::VectorXd& illuminant, std::size_t size,
                          const Eigen::Vector3d& light);

/// Rendering `index` of `renders` (render_spheres) as linear sRGB, its white (a white Lambertian facing the viewer)
/// adapted to D65 and mapped to 1 (rendering_to_linear_srgb); 0 off the sphere. InputError naming `lighting` when
/// that white is not positive (nothing maps to white).
SphereImage linear_srgb(const SphereRenders& renders, std::string_view lighting, std::size_t index = 0);
/// As above in double precision into `out` (3 values a pixel, size x size pixels; else UsageError).
void linear_srgb(const SphereRenders& renders, std::string_view lighting, std::size_t index, std::span<double> out);

}  // namespace specula::codec
