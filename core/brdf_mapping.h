#pragma once
// The mappings of reference §5.3.1 from an isotropic configuration to a point in 3D, whose Euclidean distances
// decide which scattered samples are neighbours: M_s the standard angles (theta_i, theta_o, phi_d), M_m
// Marschner's eq 5.8, M_h Rusinkiewicz's half/difference angles. Every mapping honours isotropy (eq 5.6:
// only |phi_o - phi_i| folded into [0, pi] matters); M_m and M_h honour reciprocity too (eq 5.7), M_s does not.
#include <Eigen/Core>
#include <optional>
#include <string_view>

#include "specula/core/brdf_geometry.h"

namespace specula::brdf {

enum class Mapping { standard, marschner, halfdiff };

/// Parses "standard", "marschner" or "halfdiff"; UsageError naming the choices otherwise.
Mapping parse_mapping(std::string_view name);
/// "standard", "marschner" or "halfdiff".
std::string_view mapping_name(Mapping m);
/// True when the mapping sends (theta_i, theta_o, phi_d) and (theta_o, theta_i, phi_d) to the same point.
bool mapping_is_reciprocal(Mapping m);

/// An isotropic configuration: both polar angles and |phi_o - phi_i| folded into [0, pi] (radians).
struct IsoAngles {
  double theta_i = 0, theta_o = 0, phi_d = 0;
};

/// The isotropic configuration of standard angles.
IsoAngles iso_angles(const StdAngles& a);
/// Where a configuration lies on the incidence plane at theta_i (figures 5.5-5.7, 5.17): its signed outgoing angle in
/// radians (negative on the light's side, positive towards the mirror direction) when its theta_i and its phi_d
/// (0 or pi) are both within eps of the plane's, else nullopt.
std::optional<double> incidence_plane_angle(const IsoAngles& a, double theta_i, double eps);
/// |phi_o - phi_i| folded into [0, pi].
double phi_difference(double phi_i, double phi_o);

/// The point of `a` under m: M_s (theta_i, theta_o, phi_d); M_m (sin theta_i sin theta_o, phi_d / pi,
/// cos theta_i cos theta_o); M_h (theta_h, theta_d, phi_d of the half-vector frame folded into [0, pi/2]).
Eigen::Vector3d map_angles(Mapping m, const IsoAngles& a);
/// map_angles of the isotropic configuration of `a`.
Eigen::Vector3d map_angles(Mapping m, const StdAngles& a);
/// A configuration that m sends to p (for a reciprocal mapping, one of the two, with theta_i >= theta_o for
/// M_m); p must be a point of the mapping's image (up to rounding).
IsoAngles unmap(Mapping m, const Eigen::Vector3d& p);
/// How far apart two isotropic configurations are, whatever the mapping: sqrt(|wi_a - wi_b|^2 + |wo_a - wo_b|^2)
/// over unit direction vectors, minimised over turning and mirroring b about the normal (isotropy) and, with
/// `reciprocal`, over swapping b's directions. About the angle (radians) by which the directions must move.
double config_distance(const IsoAngles& a, const IsoAngles& b, bool reciprocal);
/// A constant c with config_distance(a, b, mapping_is_reciprocal(m)) <= c |map_angles(m, a) - map_angles(m, b)| for
/// every a, b: 1 for M_s, 2 for M_h; infinity for M_m, which has none (its map is flat at the pole).
double config_distance_bound(Mapping m);

}  // namespace specula::brdf
