#include "specula/core/brdf_geometry.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace specula::brdf {
namespace {

using std::numbers::pi;

// Right-handed rotation of v by `angle` about the unit axis (Rodrigues), as BRDFRead.cpp's rotate_vector.
Eigen::Vector3d rotate(const Eigen::Vector3d& v, const Eigen::Vector3d& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return v * c + axis * (axis.dot(v) * (1 - c)) + axis.cross(v) * s;
}

const Eigen::Vector3d kNormal(0, 0, 1);
const Eigen::Vector3d kBinormal(0, 1, 0);

}  // namespace

Eigen::Vector3d direction(double theta, double phi) {
  const double s = std::sin(theta);
  return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}

Eigen::Vector2d spherical(const Eigen::Vector3d& v) {
  const Eigen::Vector3d u = v.normalized();
  const double theta = std::acos(std::clamp(u.z(), -1.0, 1.0));
  double phi = (u.x() == 0 && u.y() == 0) ? 0.0 : std::atan2(u.y(), u.x());
  if (phi == -pi) phi = pi;
  return {theta, phi};
}

HalfDiff half_diff(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const Eigen::Vector3d in = wi.normalized();
  const Eigen::Vector3d half = (in + wo.normalized()).normalized();
  const Eigen::Vector2d h = spherical(half);
  const Eigen::Vector3d diff = rotate(rotate(in, kNormal, -h[1]), kBinormal, -h[0]);
  const Eigen::Vector2d d = spherical(diff);
  return {h[0], h[1], d[0], d[1]};
}

HalfDiff half_diff(const StdAngles& a) {
  return half_diff(direction(a.theta_i, a.phi_i), direction(a.theta_o, a.phi_o));
}

void directions(const HalfDiff& h, Eigen::Vector3d& wi, Eigen::Vector3d& wo) {
  const Eigen::Vector3d d = direction(h.theta_d, h.phi_d);
  const Eigen::Vector3d d_out(-d.x(), -d.y(), d.z());
  wi = rotate(rotate(d, kBinormal, h.theta_h), kNormal, h.phi_h);
  wo = rotate(rotate(d_out, kBinormal, h.theta_h), kNormal, h.phi_h);
}

StdAngles std_angles(const HalfDiff& h) {
  Eigen::Vector3d wi, wo;
  directions(h, wi, wo);
  const Eigen::Vector2d i = spherical(wi), o = spherical(wo);
  return {i[0], i[1], o[0], o[1]};
}

namespace {
// floor(x) clamped to [0, n - 1] without the undefined int conversion of NaN or huge values.
int clamped_floor(double x, int n) {
  if (!(x > 0)) return 0;
  if (x >= n - 1) return n - 1;
  return int(x);
}
}  // namespace

int merl_theta_h_index(double theta_h) {
  if (!(theta_h > 0.0)) return 0;
  const double theta_half_deg = theta_h / (pi / 2.0) * kMerlThetaH;
  return clamped_floor(std::sqrt(theta_half_deg * kMerlThetaH), kMerlThetaH);
}

int merl_theta_d_index(double theta_d) { return clamped_floor(theta_d / (pi * 0.5) * kMerlThetaD, kMerlThetaD); }

int merl_phi_d_index(double phi_d) {
  if (phi_d < 0.0) phi_d += pi;
  return clamped_floor(phi_d / pi * kMerlPhiD, kMerlPhiD);
}

MerlCell merl_cell(const HalfDiff& h) {
  return {merl_theta_h_index(h.theta_h), merl_theta_d_index(h.theta_d), merl_phi_d_index(h.phi_d)};
}

MerlCell merl_cell(const StdAngles& a) { return merl_cell(half_diff(a)); }

HalfDiff merl_cell_centre(const MerlCell& c) {
  const double u = (c.theta_h + 0.5) / kMerlThetaH;
  return {u * u * (pi / 2), 0.0, (c.theta_d + 0.5) * (pi / 2) / kMerlThetaD, (c.phi_d + 0.5) * pi / kMerlPhiD};
}

bool merl_cell_valid(const MerlCell& c) {
  Eigen::Vector3d wi, wo;
  directions(merl_cell_centre(c), wi, wo);
  return wi.z() > 0 && wo.z() > 0;
}

}  // namespace specula::brdf
