#include "specula/acquire/scan.h"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <string>

#include "specula/core/error.h"

namespace specula::acquire {

using std::numbers::pi;

namespace {
Eigen::Vector3d sphere_centre(const ScanRig& rig) { return {rig.off_axis, rig.off_axis_y, rig.distance}; }
}  // namespace

void check_rig(const ScanRig& rig) {
  if (!(rig.focal_px > 0) || !(rig.sphere_px >= 1) || !(rig.sphere_px <= 100000))
    throw UsageError("scan rig: the focal length must be positive and the sphere 1 to 100000 pixels across");
  if (!(rig.distance > 0) || !std::isfinite(rig.off_axis) || !std::isfinite(rig.off_axis_y) ||
      !(rig.light_distance > 0))
    throw UsageError("scan rig: distances must be positive");
  const double r = sphere_radius(rig);
  if (sphere_centre(rig).norm() <= 1.05 * r) throw UsageError("scan rig: the camera is inside or on the sphere");
  if (rig.light_distance <= 1.05 * r) throw UsageError("scan rig: the light arc passes through the sphere");
  if (rig.lights == 0 || rig.lights > 100000 || !(std::abs(rig.light_step_deg) > 0) ||
      !std::isfinite(rig.first_light_deg))
    throw UsageError("scan rig: give 1 to 100000 light positions and a non-zero step");
}

double sphere_radius(const ScanRig& rig) {
  // The sphere's silhouette subtends asin(r / D) on each side: tan of it is half the diameter over the focal.
  const double half = std::atan(0.5 * rig.sphere_px / rig.focal_px);
  return sphere_centre(rig).norm() * std::sin(half);
}

std::vector<ScanPixel> scan_pixels(const ScanRig& rig) {
  check_rig(rig);
  const Eigen::Vector3d c = sphere_centre(rig);
  const double r = sphere_radius(rig);
  // The image point of the centre and a bound on the silhouette's extent there.
  const double cx = rig.focal_px * c.x() / c.z(), cy = rig.focal_px * c.y() / c.z();
  const int half = int(std::ceil(0.6 * rig.sphere_px)) + 2;
  std::vector<ScanPixel> out;
  for (int y = int(std::floor(cy)) - half; y <= int(std::floor(cy)) + half; ++y)
    for (int x = int(std::floor(cx)) - half; x <= int(std::floor(cx)) + half; ++x) {
      const Eigen::Vector3d d = Eigen::Vector3d((x + 0.5) / rig.focal_px, (y + 0.5) / rig.focal_px, 1.0).normalized();
      const double b = d.dot(c), disc = b * b - c.squaredNorm() + r * r;
      if (disc <= 0) continue;
      const Eigen::Vector3d p = (b - std::sqrt(disc)) * d;
      ScanPixel px{x, y, p, (p - c) / r, -d};
      if (px.normal.dot(px.to_camera) <= 0) continue;
      out.push_back(px);
    }
  return out;
}

Eigen::Vector3d light_position(const ScanRig& rig, std::size_t j) {
  const double a = (rig.first_light_deg + double(j) * rig.light_step_deg) * pi / 180;
  const Eigen::Vector3d c = sphere_centre(rig);
  // Turning about the vertical (y) from the direction towards the camera.
  const Eigen::Vector3d back = (-c).normalized();
  const Eigen::Vector3d side = Eigen::Vector3d::UnitY().cross(back).normalized();
  return c + rig.light_distance * (std::cos(a) * back + std::sin(a) * side);
}

bool scan_angles(const ScanPixel& p, const Eigen::Vector3d& light, brdf::StdAngles& out) {
  const Eigen::Vector3d wi = (light - p.point).normalized();
  const Eigen::Vector3d& n = p.normal;
  const double ci = n.dot(wi), co = n.dot(p.to_camera);
  if (ci <= 0 || co <= 0) return false;
  Eigen::Vector3d t = Eigen::Vector3d::UnitY() - n.y() * n;
  if (t.norm() < 1e-6) t = Eigen::Vector3d::UnitX() - n.x() * n;
  t.normalize();
  const Eigen::Vector3d b = n.cross(t);
  out = {std::acos(std::min(1.0, ci)), std::atan2(b.dot(wi), t.dot(wi)), std::acos(std::min(1.0, co)),
         std::atan2(b.dot(p.to_camera), t.dot(p.to_camera))};
  return true;
}

std::size_t scan_light(const ScanRig& rig, std::span<const ScanPixel> pixels, std::size_t j,
                       std::vector<double>& angles) {
  const Eigen::Vector3d light = light_position(rig, j);
  std::size_t added = 0;
  brdf::StdAngles a;
  for (const ScanPixel& p : pixels)
    if (scan_angles(p, light, a)) {
      angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
      ++added;
    }
  return added;
}

}  // namespace specula::acquire
