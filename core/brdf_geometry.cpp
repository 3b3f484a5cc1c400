#include "specula/core/brdf_geometry.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace specula::brdf {
namespace {

using std::numbers::pi;

// Right-handed rotation of v about the unit axis by the angle of cosine c and sine s (Rodrigues), as BRDFRead.cpp's
// rotate_vector.
Eigen::Vector3d rotate(const Eigen::Vector3d& v, const Eigen::Vector3d& axis, double c, double s) {
  return v * c + axis * (axis.dot(v) * (1 - c)) + axis.cross(v) * s;
}
Eigen::Vector3d rotate(const Eigen::Vector3d& v, const Eigen::Vector3d& axis, double angle) {
  return rotate(v, axis, std::cos(angle), std::sin(angle));
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

namespace {
// directions() from the difference vector d, the cosine and sine of theta_h, and phi_h. A turn by phi_h = 0 is left
// out: it changes nothing but the sign of a zero coordinate, which no angle here depends on.
void turn_difference(const Eigen::Vector3d& d, double cos_h, double sin_h, double phi_h, Eigen::Vector3d& wi,
                     Eigen::Vector3d& wo) {
  const Eigen::Vector3d d_out(-d.x(), -d.y(), d.z());
  wi = rotate(d, kBinormal, cos_h, sin_h);
  wo = rotate(d_out, kBinormal, cos_h, sin_h);
  if (phi_h == 0) return;
  const double c = std::cos(phi_h), s = std::sin(phi_h);
  wi = rotate(wi, kNormal, c, s);
  wo = rotate(wo, kNormal, c, s);
}

StdAngles std_angles_of(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const Eigen::Vector2d i = spherical(wi), o = spherical(wo);
  return {i[0], i[1], o[0], o[1]};
}
}  // namespace

void directions(const HalfDiff& h, Eigen::Vector3d& wi, Eigen::Vector3d& wo) {
  turn_difference(direction(h.theta_d, h.phi_d), std::cos(h.theta_h), std::sin(h.theta_h), h.phi_h, wi, wo);
}

StdAngles std_angles(const HalfDiff& h) {
  Eigen::Vector3d wi, wo;
  directions(h, wi, wo);
  return std_angles_of(wi, wo);
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

namespace {

// The neighbouring centres lo, hi = lo + 1 of continuous index x on an axis of n cells and x's share t of hi: clamped
// at the ends, or wrapped.
struct Axis {
  int lo = 0, hi = 0;
  double t = 0;
};

Axis axis_neighbours(double x, int n, bool wrap) {
  if (!wrap) x = std::clamp(x, 0.0, double(n - 1));
  const double f = std::floor(x);
  Axis a{int(f), int(f) + 1, x - f};
  if (wrap) {
    a.lo = (a.lo % n + n) % n;
    a.hi = (a.hi % n + n) % n;
  } else {
    a.hi = std::min(a.hi, n - 1);
  }
  return a;
}

}  // namespace

MerlCorners merl_trilinear(const HalfDiff& h) {
  const double phi_d = h.phi_d < 0 ? h.phi_d + pi : h.phi_d;
  const Axis ah =
      axis_neighbours(kMerlThetaH * std::sqrt(std::max(0.0, h.theta_h) / (pi / 2)) - 0.5, kMerlThetaH, false);
  const Axis ad = axis_neighbours(kMerlThetaD * h.theta_d / (pi / 2) - 0.5, kMerlThetaD, false);
  const Axis ap = axis_neighbours(kMerlPhiD * phi_d / pi - 0.5, kMerlPhiD, true);
  MerlCorners out;
  for (std::size_t c = 0; c < 8; ++c) {
    out.weight[c] = (c & 1 ? ah.t : 1 - ah.t) * (c & 2 ? ad.t : 1 - ad.t) * (c & 4 ? ap.t : 1 - ap.t);
    out.cell[c] = merl_index({c & 1 ? ah.hi : ah.lo, c & 2 ? ad.hi : ad.lo, c & 4 ? ap.hi : ap.lo});
  }
  return out;
}

MerlCentres::MerlCentres(int theta_h, int theta_d)
    : centre_(merl_cell_centre({theta_h, theta_d, 0})),
      cos_h_(std::cos(centre_.theta_h)),
      sin_h_(std::sin(centre_.theta_h)),
      cos_d_(std::cos(centre_.theta_d)),
      sin_d_(std::sin(centre_.theta_d)) {}

void MerlCentres::directions(int phi_d, Eigen::Vector3d& wi, Eigen::Vector3d& wo) const {
  // The cosine and sine of every phi_d centre, once per process.
  static const auto turns = [] {
    std::array<std::array<double, 2>, kMerlPhiD> t{};
    for (int p = 0; p < kMerlPhiD; ++p) {
      const double phi = merl_cell_centre({0, 0, p}).phi_d;
      t[std::size_t(p)] = {std::cos(phi), std::sin(phi)};
    }
    return t;
  }();
  const auto& [c, s] = turns.at(std::size_t(phi_d));
  // direction(theta_d, phi) with theta_d's sine and cosine known
  turn_difference({sin_d_ * c, sin_d_ * s, cos_d_}, cos_h_, sin_h_, 0.0, wi, wo);
}

StdAngles MerlCentres::std_angles(int phi_d) const {
  Eigen::Vector3d wi, wo;
  directions(phi_d, wi, wo);
  return std_angles_of(wi, wo);
}

}  // namespace specula::brdf
