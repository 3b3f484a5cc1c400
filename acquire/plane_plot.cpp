#include "specula/acquire/plane_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "specula/acquire/pipeline.h"
#include "specula/acquire/study.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_mapping.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// The curves' steps: theta_o = d10 / 10 degrees, signed (negative: the light's side).
constexpr int kFirstDeg10 = -895, kLastDeg10 = 895, kStepDeg10 = 5;

brdf::StdAngles plane_angles(double theta_i, int d10) {
  return brdf::StdAngles{theta_i, 0.0, std::abs(d10) / 10.0 * pi / 180, d10 > 0 ? pi : 0.0};
}

}  // namespace

std::vector<PlanePoint> incidence_plane_points(std::span<const double> angles, std::span<const float> values,
                                               std::size_t bands, double theta_i, double eps, std::size_t band) {
  const std::size_t n = angles.size() / 4;
  if (angles.size() % 4 || bands == 0 || values.size() != n * bands || band >= bands)
    throw UsageError(fmt::format("incidence_plane_points: {} angles, {} values of {} bands, band {}", angles.size(),
                                 values.size(), bands, band));
  std::vector<PlanePoint> out;
  for (std::size_t i = 0; i < n; ++i) {
    const brdf::IsoAngles a =
        brdf::iso_angles({angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]});
    if (const auto x = brdf::incidence_plane_angle(a, theta_i, eps)) out.push_back({*x, values[i * bands + band]});
  }
  return out;
}

std::string plane_points_table(std::span<const PlanePoint> points) {
  std::string t;
  for (const PlanePoint& p : points)
    t += fmt::format("{:.3f} {:.5g}\n", p.theta_o * 180 / pi, std::cbrt(std::max(0.0f, p.value)));
  return t;
}

std::string model_plane_table(const brdf::SpectralModel& model, double theta_i, std::size_t band) {
  std::vector<double> f(model.bands());
  if (band >= f.size()) throw UsageError(fmt::format("model_plane_table: band {} of {}", band, f.size()));
  std::string t;
  for (int d10 = kFirstDeg10; d10 <= kLastDeg10; d10 += kStepDeg10) {
    model.eval(plane_angles(theta_i, d10), f);
    t += fmt::format("{:.1f} {:.5g}\n", d10 / 10.0, std::cbrt(std::max(0.0, f[band])));
  }
  return t;
}

std::string grid_plane_table(const brdf::Resampler& r, const brdf::SpectralModel& model, double theta_i) {
  std::vector<double> f(model.bands());
  std::string t;
  for (int d10 = kFirstDeg10; d10 <= kLastDeg10; d10 += kStepDeg10) {
    const brdf::StdAngles at = plane_angles(theta_i, d10);
    const brdf::IsoAngles a{at.theta_i, at.theta_o, at.phi_o};
    const brdf::MerlCell cell = brdf::merl_cell(std::size_t(merl_lookup_cell(a)));
    float v = 0;
    const bool has = r.predict(brdf::std_angles(brdf::merl_cell_centre(cell)), std::span<float>(&v, 1));
    model.eval(at, f);
    t += fmt::format("{:.1f} {} {:.5g}\n", d10 / 10.0,
                     has ? fmt::format("{:.5g}", std::cbrt(std::max(0.0f, v))) : "NaN", std::cbrt(f[0]));
  }
  return t;
}

std::string target_table(const TargetReport& r, std::span<const double> bands) {
  const Eigen::VectorXd& first = r.filters.size() ? r.filters : r.delta;
  std::string t;
  for (Eigen::Index b = 0; b < r.truth.size(); ++b)
    t += fmt::format("{} {} {} {}\n", bands[std::size_t(b)], r.truth[b], first[b],
                     r.factored.size() ? fmt::format("{}", r.factored[b]) : std::string("NaN"));
  return t;
}

}  // namespace specula::acquire
