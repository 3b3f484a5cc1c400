#pragma once
// BRDF angles: standard spherical angles (theta_i, phi_i, theta_o, phi_o), direction vectors, the
// half/difference angles of Rusinkiewicz (1998), and the MERL grid (Matusik et al. 2003) indexed exactly
// as MERL's reference BRDFRead.cpp does. Angles are radians; z is the surface normal; both directions
// point away from the surface.
#include <Eigen/Core>
#include <array>
#include <cstddef>

namespace specula::brdf {

/// Incident and outgoing directions in spherical angles (theta from the normal, phi from the tangent x).
struct StdAngles {
  double theta_i = 0, phi_i = 0, theta_o = 0, phi_o = 0;
};

/// Rusinkiewicz half/difference angles: the half vector (theta_h, phi_h) and the incident direction seen
/// in the frame where the half vector is the pole (theta_d, phi_d).
struct HalfDiff {
  double theta_h = 0, phi_h = 0, theta_d = 0, phi_d = 0;
};

/// Unit vector (sin t cos p, sin t sin p, cos t).
Eigen::Vector3d direction(double theta, double phi);
/// Spherical angles of a non-zero vector: theta in [0, pi], phi in (-pi, pi] (0 on the pole).
Eigen::Vector2d spherical(const Eigen::Vector3d& v);

/// Half/difference angles of (wi, wo) as MERL's std_coords_to_half_diff_coords: phi_h, phi_d in (-pi, pi].
/// wi + wo must not vanish.
HalfDiff half_diff(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo);
/// half_diff of the directions of `a`.
HalfDiff half_diff(const StdAngles& a);
/// The inverse of half_diff: wi = Rz(phi_h) Ry(theta_h) d, wo likewise from d turned by pi about the half vector.
void directions(const HalfDiff& h, Eigen::Vector3d& wi, Eigen::Vector3d& wo);
/// Standard angles of the directions of h (phi in (-pi, pi]).
StdAngles std_angles(const HalfDiff& h);

/// The MERL grid: 90 theta_h x 90 theta_d x 180 phi_d cells, phi_d fastest, theta_h slowest.
inline constexpr int kMerlThetaH = 90;
inline constexpr int kMerlThetaD = 90;
inline constexpr int kMerlPhiD = 180;
inline constexpr std::size_t kMerlCells = std::size_t(kMerlThetaH) * kMerlThetaD * kMerlPhiD;

/// One MERL cell by its three indices.
struct MerlCell {
  int theta_h = 0, theta_d = 0, phi_d = 0;
};

/// BRDFRead.cpp theta_half_index: floor(90 sqrt(theta_h / (pi/2))), clamped to [0, 89] (NaN gives 0, as do the others).
int merl_theta_h_index(double theta_h);
/// BRDFRead.cpp theta_diff_index: floor(90 theta_d / (pi/2)), clamped to [0, 89].
int merl_theta_d_index(double theta_d);
/// BRDFRead.cpp phi_diff_index: phi_d < 0 shifted by pi (reciprocity), floor(180 phi_d / pi), clamped to [0, 179].
int merl_phi_d_index(double phi_d);
/// Linear index phi_d + 180 (theta_d + 90 theta_h) of a cell.
constexpr std::size_t merl_index(const MerlCell& c) {
  return std::size_t(c.phi_d) +
         std::size_t(kMerlPhiD) * (std::size_t(c.theta_d) + std::size_t(kMerlThetaD) * std::size_t(c.theta_h));
}
/// The cell holding half/difference angles h (phi_h ignored: isotropy).
MerlCell merl_cell(const HalfDiff& h);
/// The cell BRDFRead.cpp's lookup_brdf_val reads for the standard angles a.
MerlCell merl_cell(const StdAngles& a);
/// The three indices of linear index `index` (< kMerlCells).
constexpr MerlCell merl_cell(std::size_t index) {
  return {int(index / (std::size_t(kMerlPhiD) * kMerlThetaD)), int(index / kMerlPhiD % kMerlThetaD),
          int(index % kMerlPhiD)};
}
/// Angles of the cell centre, taken in index space: theta_h = ((i + 1/2) / 90)^2 pi/2, theta_d = (j + 1/2) pi/180,
/// phi_d = (k + 1/2) pi/180, phi_h = 0; merl_cell of the result is the cell again.
HalfDiff merl_cell_centre(const MerlCell& c);
/// True when both directions of the cell centre lie above the horizon (theta_i, theta_o < pi/2).
bool merl_cell_valid(const MerlCell& c);

/// The 8 cell centres around a configuration in MERL index space and their trilinear weights.
struct MerlCorners {
  std::array<std::size_t, 8> cell{};  ///< linear indices (merl_index); a corner may repeat at a clamped end
  std::array<double, 8> weight{};     ///< summing to 1
};
/// The corners of h in index space (90 sqrt(theta_h / (pi/2)), 90 theta_d / (pi/2), 180 phi_d / pi, each less 1/2,
/// a cell's centre at its index): clamped at the ends of theta_h and theta_d, phi_d wrapping at pi (reciprocity).
MerlCorners merl_trilinear(const HalfDiff& h);

/// The cell centres of one (theta_h, theta_d) of the MERL grid with the trigonometry they share computed once:
/// what directions and std_angles of merl_cell_centre({theta_h, theta_d, phi_d}) give, bit for bit.
class MerlCentres {
 public:
  MerlCentres(int theta_h, int theta_d);
  /// directions(merl_cell_centre({theta_h, theta_d, phi_d}), wi, wo).
  void directions(int phi_d, Eigen::Vector3d& wi, Eigen::Vector3d& wo) const;
  /// std_angles(merl_cell_centre({theta_h, theta_d, phi_d})).
  StdAngles std_angles(int phi_d) const;

 private:
  HalfDiff centre_;
  double cos_h_, sin_h_, cos_d_, sin_d_;
};

}  // namespace specula::brdf
