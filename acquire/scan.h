#pragma once
// The sample configurations of the reference's rig (§5.2) computed directly, without images: a pinhole camera
// at the origin looking along +z (image rows along +y), a sphere slightly off the optical axis, a point light
// moved on a horizontal arc around the sphere. Every pixel whose ray meets the sphere gives a surface point,
// its normal and view vector; every light position that lights that point gives one sample (theta_i, phi_i,
// theta_o, phi_o) in the frame of the normal (tangent: the image's up direction projected onto the tangent plane).
#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <vector>

#include "specula/core/brdf_geometry.h"

namespace specula::acquire {

struct ScanRig {
  double focal_px = 2000;       ///< focal length in pixels
  double sphere_px = 200;       ///< the sphere's diameter on the image, about (pixels)
  double distance = 1.0;        ///< camera to sphere centre (m)
  double off_axis = 0.03;       ///< sphere centre's offset from the optical axis along x (m)
  double off_axis_y = 0.011;    ///< and along y, so that the image is not mirror-symmetric about the arc's plane
  double light_distance = 1.0;  ///< arc radius: light to sphere centre (m)
  double first_light_deg = 10;  ///< angle between the first light and the camera, seen from the sphere
  double light_step_deg = 1;    ///< arc step
  std::size_t lights = 165;     ///< light positions
};

/// One visible point of the sphere: its pixel, position (camera frame, m), normal and direction to the camera.
struct ScanPixel {
  int x = 0, y = 0;
  Eigen::Vector3d point, normal, to_camera;
};

/// UsageError stating the rule when the rig cannot be imaged (non-positive sizes or distances, a camera or
/// light inside the sphere, no lights, a step of 0).
void check_rig(const ScanRig& rig);
/// The sphere's radius (m) from its size on the image.
double sphere_radius(const ScanRig& rig);
/// Every pixel (row-major over the image's bounding square of the sphere) whose centre's ray meets the sphere.
std::vector<ScanPixel> scan_pixels(const ScanRig& rig);
/// Position of light j (camera frame, m).
Eigen::Vector3d light_position(const ScanRig& rig, std::size_t j);
/// The configuration of pixel p lit by a light at `light` in the frame of p's normal; false when the point
/// is not lit (light at or below its horizon).
bool scan_angles(const ScanPixel& p, const Eigen::Vector3d& light, brdf::StdAngles& out);
/// Every lit sample of light j in pixel order, appended to angles (n x 4). Returns how many were added.
std::size_t scan_light(const ScanRig& rig, std::span<const ScanPixel> pixels, std::size_t j,
                       std::vector<double>& angles);

}  // namespace specula::acquire
