#pragma once
// The reference's evaluation of resampling (§5.4, figures 5.9-5.16): samples of an analytic BRDF at a scan's
// configurations are reconstructed on the MERL grid for each mapping, k and weighting, a sphere is rendered
// with the reconstruction and with the analytic model, and the average per-pixel L1 difference is reported.
// The render looks BRDF values up in the grid as MERL's BRDFRead.cpp does, so only the cells the sphere shows
// are reconstructed: the numbers are those of the whole grid.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "specula/core/brdf_models.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// A square rendering of a unit sphere seen orthographically along -z: value per pixel (row-major, rows top to
/// bottom) and whether the sphere covers it.
struct SphereRender {
  std::size_t size = 0;
  std::vector<double> value;
  std::vector<std::uint8_t> covered;
};

/// BRDF value of an isotropic configuration; false when there is none (the pixel is drawn as 0).
using IsoBrdf = std::function<bool(const brdf::IsoAngles& at, double& f)>;

/// Renders f on a size x size sphere: pixel centre (x, y) in [-1, 1]^2 inside the disc has normal
/// (x, y, sqrt(1 - x^2 - y^2)), the viewer is at +z, a directional light of irradiance pi comes from `light`;
/// value pi f cos(theta_i) where the light is above the horizon, else 0. UsageError for size 0 or a zero light.
SphereRender render_sphere(std::size_t size, const Eigen::Vector3d& light, const IsoBrdf& f);

/// The MERL cell the grid lookup reads for configuration a (as BRDFRead.cpp).
std::size_t merl_lookup_cell(const brdf::IsoAngles& a);

/// One reconstruction of the study.
struct StudyResult {
  brdf::Mapping mapping = brdf::Mapping::standard;
  std::size_t k = 1;
  brdf::Weights weights = brdf::Weights::mean;  ///< irrelevant when k = 1
  double l1 = 0;                                ///< mean |reconstruction - truth| over the sphere's pixels
  double max_error = 0;                         ///< largest per-pixel difference
  std::size_t pixels_without_data = 0;          ///< sphere pixels whose cell has no support
};

struct StudyOptions {
  std::vector<std::size_t> ks = {1, 16, 64, 256};
  std::size_t render_size = 200;
  Eigen::Vector3d light = Eigen::Vector3d(-0.5, 0.5, std::sqrt(0.5));  ///< theta 45 deg from the viewer, phi 135 deg
  double max_gap = 0.15;
};

/// Renders of the truth (the model at each pixel) and of the model sampled at the cell centres (the error of the
/// grid alone), plus one row per mapping x k x weighting (k = 1 once, as "nearest"), in that order. band picks
/// the model's band; the samples (angles n x 4, values n x bands) are the model's values at the scan.
struct StudyOutput {
  SphereRender truth, grid_truth;
  double grid_l1 = 0;
  std::vector<StudyResult> rows;
  std::vector<SphereRender> renders;  ///< one per row
};
/// Runs the study; UsageError for bad options or sizes.
StudyOutput resampling_study(const brdf::SpectralModel& model, std::size_t band, std::span<const double> angles,
                             std::span<const float> values, const StudyOptions& o);

/// An 8-bit RGB picture, rows top to bottom.
struct Rgb8Sheet {
  std::size_t width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< 3 x width x height
};
/// The study's renders side by side, `per_row` panels a row: the truth, the model at cell centres, then every row's
/// render, grey as the material is, tone-mapped alike (the truth's brightest pixel as white, gamma 2.2), background
/// 32. UsageError for per_row 0.
Rgb8Sheet study_sheet(const StudyOutput& s, std::size_t per_row);

}  // namespace specula::acquire
