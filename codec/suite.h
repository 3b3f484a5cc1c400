#pragma once
// The lighting suite: one fixed set of renderings under which two spectral BRDF grids are compared, so that a
// BRDF is judged the way many scenes would see it rather than by one picture (docs/brdf.md, "The lighting
// suite"). A sphere is seen from two views (head-on along the sample normal, and 60 degrees off it) under the
// built-in environment and nine directional lights (0, 31, 61, 81 and 105 degrees from the normal, two
// azimuths) in D65 and in illuminant A: 38 conditions. Each rendering is exposed by the reference's own
// brightness; cells without data render black and are counted.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "specula/codec/environment.h"
#include "specula/store/store.h"

namespace specula::codec {

/// One rendering condition of the suite. Lights and views are given in the world frame, whose +z is the
/// sample normal (the head-on view); +y is up (the environment's zenith).
struct SuiteCondition {
  std::string name;                    ///< e.g. "head-on D65 60/90"
  std::size_t view = 0;                ///< 0: head-on, 1: 60 degrees off the normal
  std::string light;                   ///< "environment", "D65" or "A"
  double elevation_deg = 0;            ///< directional: angle of the light from the normal (+z); environment: 0
  double azimuth_deg = 0;              ///< directional: azimuth of the light around +z from +x
  Eigen::Vector3d direction{0, 0, 1};  ///< directional: unit vector towards the light, world frame
};

/// The suite's settings: its definition is fixed; only the sphere size and the environment may be chosen.
struct SuiteOptions {
  std::size_t size = 64;  ///< sphere diameter in pixels (16 to 1024)
  /// Lights of the environment conditions: the map split into this many regions (plus the sun).
  std::size_t env_regions_w = 32, env_regions_h = 16;
};

/// Every condition rendered for one grid: per condition XYZ (3 floats per disc pixel, disc pixels in
/// LightingSuite::pixel order), and per unique cell looked up whether the grid has data there.
struct SuiteRenders {
  std::vector<std::vector<float>> xyz;
  std::vector<std::uint8_t> cell_valid;
};

/// ΔE00 of one condition over its compared pixels: the lit ones (some light of the condition reaches them) that
/// the reference has data for (at least one of their cells).
struct ConditionDiff {
  double de00_mean = 0, de00_p95 = 0, de00_max = 0;
  std::size_t pixels = 0;         ///< pixels compared
  std::size_t unseen_pixels = 0;  ///< lit pixels the reference has no data for: black in it, not compared
  std::size_t hole_pixels = 0;    ///< of them, lit through a cell the reference has and the compared grid lacks
  Eigen::Vector3d white = Eigen::Vector3d::Zero();  ///< the exposure's reference white (XYZ)
};

/// The suite's verdict on grid b against reference a.
struct SuiteDiff {
  std::vector<ConditionDiff> conditions;  ///< in LightingSuite::conditions() order
  /// Pooled over the compared pixels of every condition: mean, 95th percentile (rank ceil(0.95 n)), max.
  double de00_mean = 0, de00_p95 = 0, de00_max = 0;
  std::size_t worst = 0;  ///< the condition of largest ΔE00 mean
  std::size_t pixels = 0, hole_pixels = 0, unseen_pixels = 0;
  /// Per condition, ΔE00 per disc pixel (0 where not compared); filled when asked (keep_maps).
  std::vector<std::vector<float>> de00;
  /// Value metrics (suite_value_metrics); filled by suite_diff.
  std::uint64_t cells = 0;        ///< valid in the reference
  std::uint64_t hole_cells = 0;   ///< valid in the reference, without data in b (render black)
  std::uint64_t extra_cells = 0;  ///< with data in b only
  double rel_rms_cos = 0;
  std::array<double, 4> albedo_a{}, albedo_b{}, albedo_rel_error{};  ///< at kSuiteAlbedoAngles
};

/// The pooled 95th-percentile ΔE00 target that goes with a pooled mean target `de00_mean` when none is given: 3x.
constexpr double default_p95_target(double de00_mean) { return 3 * de00_mean; }

/// The largest single-condition ΔE00 mean that a pooled mean target `de00_mean` allows: 2x.
constexpr double condition_mean_target(double de00_mean) { return 2 * de00_mean; }

/// The incidence angles (degrees) at which the suite compares directional albedo.
inline constexpr std::array<double, 4> kSuiteAlbedoAngles{0, 30, 60, 80};

/// The suite's fixed conditions with their per-pixel direction pairs and MERL cells set up once, so that a
/// grid renders under all of them in one pass. Thread-safe const methods; results do not depend on the thread
/// count.
class LightingSuite {
 public:
  /// The suite on `grid`'s wavelengths with the built-in environment (default_environment).
  explicit LightingSuite(const WavelengthGrid& grid, const SuiteOptions& options = {});
  /// The suite with `env` (on its wavelengths) in place of the built-in environment.
  LightingSuite(const Environment& env, const SuiteOptions& options);

  const std::vector<SuiteCondition>& conditions() const { return conditions_; }
  const WavelengthGrid& wavelengths() const { return wavelengths_; }
  std::size_t size() const { return size_; }
  /// Disc pixels as row-major indices into size x size.
  const std::vector<std::uint32_t>& pixels() const { return pixels_; }
  /// Per condition, 1 for each disc pixel some light of the condition reaches.
  const std::vector<std::uint8_t>& lit(std::size_t condition) const { return geometry_[cond_geometry_[condition]].lit; }
  /// The view direction of view v (world frame), and its camera axes (image x right, y up).
  Eigen::Vector3d view_direction(std::size_t view) const;
  Eigen::Matrix3d camera(std::size_t view) const;
  /// The environment's region lights the environment conditions use (world frame).
  const EnvironmentLights& environment_lights() const { return env_lights_; }
  /// The spectral power of a directional condition's light (B values, relative): D65 or A.
  const Eigen::VectorXd& illuminant(std::size_t condition) const;
  /// The 3 x B matrix taking a spectral radiance to XYZ (CIE 1931 2 degree, equal-energy normalisation).
  const Eigen::Matrix<double, 3, Eigen::Dynamic>& to_xyz() const { return to_xyz_; }

  /// Renders `grid` (on the suite's wavelengths, else InputError) under every condition.
  SuiteRenders render(const store::Grid& grid) const;
  /// ΔE00 of `test` against `reference` per condition and pooled, each condition exposed from the reference
  /// (docs/brdf.md); keep_maps fills SuiteDiff::de00.
  SuiteDiff compare(const SuiteRenders& reference, const SuiteRenders& test, bool keep_maps = false) const;

 private:
  struct Geometry;
  void setup(const Environment& env, const SuiteOptions& options);

  WavelengthGrid wavelengths_;
  std::size_t size_ = 0;
  std::vector<SuiteCondition> conditions_;
  std::vector<std::size_t> cond_geometry_;
  std::vector<std::uint32_t> pixels_;
  struct Geometry {
    std::size_t view = 0;
    bool environment = false;
    std::vector<std::uint32_t> offsets;  // per pixel, its first pair (pixels + 1 entries)
    std::vector<std::uint32_t> cell;     // per pair, index into cells_
    std::vector<std::uint32_t> light;    // per pair
    std::vector<float> weight;           // per pair: cosine (times the region's |m|)
    std::vector<std::uint8_t> lit;       // per pixel
  };
  std::vector<Geometry> geometry_;
  std::vector<std::uint32_t> cells_;  // the unique MERL cells looked up, ascending
  EnvironmentLights env_lights_;
  Eigen::VectorXd d65_, a_;
  Eigen::Matrix<double, 3, Eigen::Dynamic> to_xyz_;
  Eigen::Vector3d env_white_ = Eigen::Vector3d::Zero();
};

/// Directional albedo rho(theta_i) = integral of f(wi, wo) cos theta_o d wo of `grid` at each kSuiteAlbedoAngles,
/// as luminance: the D65-weighted Y of the per-band albedo over the Y of D65 (cells without data count 0). The
/// integral runs over 128 x 180 midpoint nodes uniform in cos^2 theta_o and phi_o (projected solid angle).
std::array<double, 4> suite_albedo(const store::Grid& grid);

/// The suite's value metrics of b against a, into d: cells, hole_cells, extra_cells; rel_rms_cos over the cells
/// valid in a (b's holes as 0), weight cos theta_i cos theta_o at the cell centre; the albedo and its relative error.
void suite_value_metrics(const store::Grid& a, const store::Grid& b, SuiteDiff& d);

/// Renders a and b under `suite`, compares them and adds the value metrics. InputError if the grids' wavelengths
/// differ from the suite's.
SuiteDiff suite_diff(const store::Grid& a, const store::Grid& b, const LightingSuite& suite, bool keep_maps = false);

/// d as one JSON object (text): the pooled ΔE00, the worst condition, holes, the value metrics, and every
/// condition with its definition and ΔE00 mean, p95, max, pixels and hole pixels.
std::string suite_json(const SuiteDiff& d, const LightingSuite& suite);

}  // namespace specula::codec
