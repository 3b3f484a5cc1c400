#pragma once
// Scattered BRDF samples onto the MERL grid (reference §5.3): the samples' angles mapped into a 3D space
// (M_s standard, M_m Marschner eq 5.8, M_h Rusinkiewicz half/difference), a kd-tree over them (nanoflann),
// and at every query (a grid cell's centre, or any angles) the k nearest samples combined with one set of
// weights for every band: their mean, or Shepard's inverse distances to the power p (eqs 5.9-5.10).
#include <Eigen/Core>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "core/brdf_geometry.h"

namespace specula::acquire {

enum class Mapping { standard, marschner, halfdiff };
enum class Weights { mean, shepard };

/// Parses "standard", "marschner" or "halfdiff"; UsageError with the choices otherwise.
Mapping parse_mapping(std::string_view name);
std::string_view mapping_name(Mapping m);
/// Parses "mean" or "shepard"; UsageError otherwise.
Weights parse_weights(std::string_view name);

/// The point of an isotropic configuration under mapping m (radians): M_s (theta_i, theta_o, phi_d),
/// M_m (sin theta_i sin theta_o, phi_d / pi, cos theta_i cos theta_o), M_h (theta_h, theta_d, phi_d of the
/// half vector frame); phi_d folded into [0, pi] in every case.
Eigen::Vector3d map_angles(Mapping m, const brdf::StdAngles& a);

struct ResampleOptions {
  Mapping mapping = Mapping::standard;
  std::size_t k = 32;
  Weights weights = Weights::shepard;
  double power = 1;
  /// A grid cell is left without data when its nearest sample is farther than this in (theta_i, theta_o,
  /// phi_d) (radians, Euclidean), whatever the mapping.
  double max_gap = 0.15;
};

/// A kd-tree over n samples; the samples' values stay with the caller and must outlive it.
class Resampler {
 public:
  /// angles: n x 4 (theta_i, phi_i, theta_o, phi_o, radians); values: n x bands. UsageError for bad options
  /// (k = 0, p < 0 or not finite) or sizes, InputError for no samples.
  Resampler(std::span<const double> angles, std::span<const float> values, std::size_t bands, const ResampleOptions& o);
  ~Resampler();
  Resampler(const Resampler&) = delete;
  Resampler& operator=(const Resampler&) = delete;

  std::size_t size() const { return n_; }
  std::size_t bands() const { return bands_; }
  /// The prediction at `at` into out (bands values); false (and out untouched) when the nearest sample is
  /// farther than max_gap.
  bool predict(const brdf::StdAngles& at, std::span<float> out) const;
  /// The k nearest samples of `at` (indices, nearest first) and their squared mapped distances.
  void neighbours(const brdf::StdAngles& at, std::vector<std::size_t>& index, std::vector<double>& dist2) const;
  /// Every physically valid MERL cell's centre predicted into grid (bands x 90 x 90 x 180, band slowest); cells
  /// without support or below the horizon get -1. OpenMP over cells; the same for any thread count. Returns
  /// the number of cells with data.
  std::size_t fill_grid(std::span<float> grid) const;

 private:
  struct Tree;
  std::size_t n_ = 0, bands_ = 0;
  ResampleOptions o_;
  std::span<const double> angles_;
  std::span<const float> values_;
  std::unique_ptr<Tree> tree_;
};

}  // namespace specula::acquire
