#pragma once
// Geometric calibration of a capture (reference §5.2): the sphere's circle on the backlit silhouette (eq 5.1),
// the sphere in camera space (eq 5.2), per-pixel normals and view vectors by ray casting, light directions from
// the mirror sphere's highlight (eq 5.3), and the spatial response S(x, y) from flat fields (§4.1.2).
#include <Eigen/Core>
#include <functional>
#include <span>
#include <vector>

namespace specula::acquire {

/// Nelder-Mead simplex minimisation (Nelder & Mead 1965; standard coefficients 1, 2, 0.5, 0.5).
struct SimplexResult {
  Eigen::VectorXd x;
  double value = 0;
  int iterations = 0;
  bool converged = false;  ///< the simplex's values spread less than tol before max_iterations
};
/// Minimises f from x0 with initial steps `step` (one per coordinate). Deterministic.
SimplexResult nelder_mead(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x0,
                          const Eigen::VectorXd& step, int max_iterations = 2000, double tol = 1e-10);

/// A circle on the image (pixels; pixel (u, v) has its centre at (u + 0.5, v + 0.5)).
struct Circle {
  double cx = 0, cy = 0, r = 0;
};

/// A greyscale image, row-major.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<float> value;
  float at(int u, int v) const { return value[std::size_t(v) * std::size_t(width) + std::size_t(u)]; }
};

/// The sphere's circle on a backlit silhouette (dark disc on a bright board): an initial guess from the dark
/// pixels' area and centroid, refined by Nelder-Mead on eq 5.1, -sum over n points on the circle of the
/// gradient magnitude (of the image smoothed by a Gaussian of 1 px, bilinearly interpolated). InputError when
/// the image shows no dark disc.
Circle detect_circle(const GreyImage& silhouette, int n = 32);

/// A pinhole camera: focal length and principal point in pixels.
struct Pinhole {
  double focal = 0, cx = 0, cy = 0;
  /// Unit ray through pixel position (x, y) (pixel centres at half-integers).
  Eigen::Vector3d ray(double x, double y) const {
    return Eigen::Vector3d((x - cx) / focal, (y - cy) / focal, 1).normalized();
  }
};

/// A sphere in camera space (m).
struct Sphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0;
  /// Distance along unit ray d from the origin to the near intersection; false when the ray misses.
  bool hit(const Eigen::Vector3d& d, double& t) const;
};

/// The sphere whose ray-traced silhouette matches `circle` (eq 5.2): a silhouette fixes the sphere's direction
/// and angular size but not its distance, so the radius is `radius` (the sample's known size; any positive
/// value gives the same normals). Starts from the circle's cone and refines the centre by Nelder-Mead on the
/// disagreement (XOR, with 4 x 4 supersampling for sub-pixel resolution) between the traced silhouette and the
/// circle's disc.
Sphere fit_sphere(const Circle& circle, const Pinhole& camera, double radius, int width, int height);

/// The light's direction from the sphere's centre, from a mirror-sphere image: the highlight found by template
/// matching (the brightest 3 x 3 mean, then its intensity-weighted centroid), the reflection of the view ray
/// there (eq 5.3), and, when light_distance > 0, the point at that distance from the centre along the reflected
/// ray (a finite arc); else the reflected direction (a distant light). InputError when there is no highlight on
/// the sphere.
/// *confidence (optional) gets cos of the angle between the normal at the highlight and the view: near the limb a
/// pixel spans many degrees of reflected directions and the estimate is poorer.
Eigen::Vector3d light_direction(const GreyImage& mirror, const Pinhole& camera, const Sphere& sphere,
                                double light_distance, double* confidence = nullptr);

/// The lights' directions as the arc they lie on: the rotation R taking (cos a, sin a, 0) (a: each light's arc
/// angle from the manifest) closest to the measured directions in the weighted least-squares sense (Wahba's
/// problem, solved by SVD), and R (cos a, sin a, 0) for every light, measured or not (weight 0). UsageError for
/// fewer than 2 weighted lights or mismatched sizes.
std::vector<Eigen::Vector3d> fit_light_arc(std::span<const Eigen::Vector3d> measured, std::span<const double> weights,
                                           std::span<const double> angles_deg);

/// Spatial response S(x, y) in (0, 1] from flat fields (one per band): each divided by the mean of its central
/// 5 % of pixels, then averaged over bands (§4.1.2), so the centre is 1, and smoothed by a least-squares 2-D
/// polynomial of degree 4 (vignetting is smooth; the flats' pixel noise is not). UsageError for no images or
/// mixed sizes.
GreyImage spatial_response(std::span<const GreyImage> flats);

}  // namespace specula::acquire
