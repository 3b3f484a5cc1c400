#include "specula/core/brdf_mapping.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "specula/core/error.h"

namespace specula::brdf {

using std::numbers::pi;

Mapping parse_mapping(std::string_view name) {
  if (name == "standard") return Mapping::standard;
  if (name == "marschner") return Mapping::marschner;
  if (name == "halfdiff") return Mapping::halfdiff;
  throw UsageError("mapping '" + std::string(name) +
                   "': use standard (M_s), marschner (M_m, eq 5.8) or halfdiff (M_h)");
}

std::string_view mapping_name(Mapping m) {
  switch (m) {
    case Mapping::standard:
      return "standard";
    case Mapping::marschner:
      return "marschner";
    case Mapping::halfdiff:
      return "halfdiff";
  }
  return "?";
}

bool mapping_is_reciprocal(Mapping m) { return m != Mapping::standard; }

double phi_difference(double phi_i, double phi_o) {
  const double d = std::fmod(std::abs(phi_o - phi_i), 2 * pi);
  return d > pi ? 2 * pi - d : d;
}

IsoAngles iso_angles(const StdAngles& a) { return {a.theta_i, a.theta_o, phi_difference(a.phi_i, a.phi_o)}; }

std::optional<double> incidence_plane_angle(const IsoAngles& a, double theta_i, double eps) {
  if (std::abs(a.theta_i - theta_i) > eps || (a.phi_d > eps && a.phi_d < pi - eps)) return std::nullopt;
  return (a.phi_d > pi / 2 ? 1 : -1) * a.theta_o;
}

Eigen::Vector3d map_angles(Mapping m, const IsoAngles& a) {
  switch (m) {
    case Mapping::standard:
      return {a.theta_i, a.theta_o, a.phi_d};
    case Mapping::marschner:
      return {std::sin(a.theta_i) * std::sin(a.theta_o), a.phi_d / pi, std::cos(a.theta_i) * std::cos(a.theta_o)};
    case Mapping::halfdiff: {
      const HalfDiff h = half_diff(StdAngles{a.theta_i, 0.0, a.theta_o, a.phi_d});
      // phi_d of the half-vector frame: mirroring (isotropy) negates it, reciprocity adds pi; [0, pi/2] is
      // what both leave.
      const double d = phi_difference(0.0, h.phi_d);
      return {h.theta_h, h.theta_d, d > pi / 2 ? pi - d : d};
    }
  }
  return {};
}

Eigen::Vector3d map_angles(Mapping m, const StdAngles& a) { return map_angles(m, iso_angles(a)); }

IsoAngles unmap(Mapping m, const Eigen::Vector3d& p) {
  switch (m) {
    case Mapping::standard:
      return {p[0], p[1], p[2]};
    case Mapping::marschner: {
      // cos(theta_i - theta_o) = c + s and cos(theta_i + theta_o) = c - s.
      const double sum = std::acos(std::clamp(p[2] - p[0], -1.0, 1.0));
      const double diff = std::acos(std::clamp(p[2] + p[0], -1.0, 1.0));
      return {0.5 * (sum + diff), 0.5 * (sum - diff), std::clamp(p[1], 0.0, 1.0) * pi};
    }
    case Mapping::halfdiff: {
      const StdAngles a = std_angles(HalfDiff{p[0], 0.0, p[1], p[2]});
      return iso_angles(a);
    }
  }
  return {};
}

namespace {
// The distance for b's directions given as they are (phi_i = 0, phi_o = phi_d, or mirrored): with R turning
// about the normal by psi, sum |u - R v|^2 = 4 - 2 (A cos psi + B sin psi + C), least at sqrt(A^2 + B^2) + C.
double turned_distance(const Eigen::Vector3d& ai, const Eigen::Vector3d& ao, const Eigen::Vector3d& bi,
                       const Eigen::Vector3d& bo) {
  const double A = ai.x() * bi.x() + ai.y() * bi.y() + ao.x() * bo.x() + ao.y() * bo.y();
  const double B = ai.y() * bi.x() - ai.x() * bi.y() + ao.y() * bo.x() - ao.x() * bo.y();
  const double C = ai.z() * bi.z() + ao.z() * bo.z();
  return std::sqrt(std::max(0.0, 4 - 2 * (std::hypot(A, B) + C)));
}
}  // namespace

double config_distance(const IsoAngles& a, const IsoAngles& b, bool reciprocal) {
  const Eigen::Vector3d ai = direction(a.theta_i, 0), ao = direction(a.theta_o, a.phi_d);
  double best = std::numeric_limits<double>::infinity();
  for (const bool swap : {false, true}) {
    if (swap && !reciprocal) break;
    const double ti = swap ? b.theta_o : b.theta_i, to = swap ? b.theta_i : b.theta_o;
    const Eigen::Vector3d bi = direction(ti, 0), bo = direction(to, b.phi_d);
    best = std::min({best, turned_distance(ai, ao, bi, bo), turned_distance(ai, ao, bi, {bo.x(), -bo.y(), bo.z()})});
  }
  return best;
}

// M_s: wi moves by at most |d theta_i| (both at phi = 0), wo by at most sqrt(d theta_o^2 + d phi_d^2) (the sphere's
// metric d theta^2 + sin^2 theta d phi^2). M_h: with phi_h = 0 each of wi = Ry(theta_h) d(theta_d, phi_d) and wo moves
// by at most |d theta_h| + sqrt(d theta_d^2 + d phi_d^2) <= sqrt(2) |dp|, so both together by 2 |dp|; the folds of
// phi_d are mirrorings and swaps, over which config_distance minimises.
double config_distance_bound(Mapping m) {
  switch (m) {
    case Mapping::standard:
      return 1;
    case Mapping::halfdiff:
      return 2;
    case Mapping::marschner:
      break;
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace specula::brdf
