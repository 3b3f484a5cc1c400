#pragma once
// An evaluation of the lighting suite written apart from codec/suite.cpp (docs/brdf.md, "The lighting suite"):
// per pixel, its own view frames and tangent frame, standard angles and brdf::merl_cell(StdAngles), its own
// exposure and CIEDE2000 pooling. Tests check the suite and the codec's target against it.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "specula/codec/spc_target.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/colour.h"

namespace specula::test {

inline constexpr double kRefPi = std::numbers::pi;

// The view of the suite's definition (docs/brdf.md), written out here: head-on along +z, or 60 degrees off the
// normal towards +y; image x is world +x, image y completes the frame.
inline void view_axes(std::size_t view, Eigen::Vector3d& x, Eigen::Vector3d& y, Eigen::Vector3d& z) {
  const double a = view == 0 ? 0 : kRefPi / 3;
  z = {0, std::sin(a), std::cos(a)};
  x = {1, 0, 0};
  y = z.cross(x);
}

// Brute force: the spectral radiance leaving pixel `pix` under condition c, with the lights of the condition,
// standard angles in a frame built from the normal and the cell found by brdf::merl_cell(StdAngles).
inline Eigen::VectorXd brute_force(const store::Grid& g, const codec::LightingSuite& s, std::size_t c, std::size_t pix,
                                   bool* any_data = nullptr) {
  const codec::SuiteCondition& cond = s.conditions()[c];
  Eigen::Vector3d ax, ay, az;
  view_axes(cond.view, ax, ay, az);
  const double px = 2 * (double(pix % s.size()) + 0.5) / double(s.size()) - 1;
  const double py = 1 - 2 * (double(pix / s.size()) + 0.5) / double(s.size());
  const Eigen::Vector3d n = px * ax + py * ay + std::sqrt(1 - px * px - py * py) * az;
  const Eigen::Vector3d t = (Eigen::Vector3d(0.3, 0.7, -0.2) - Eigen::Vector3d(0.3, 0.7, -0.2).dot(n) * n).normalized();
  const Eigen::Vector3d b = n.cross(t);
  std::vector<Eigen::Vector3d> dirs;
  std::vector<Eigen::VectorXd> power;
  if (cond.light == "environment") {
    const codec::EnvironmentLights& l = s.environment_lights();
    for (std::size_t j = 0; j < l.count; ++j) {
      dirs.push_back(l.dir[j]);
      Eigen::VectorXd p(Eigen::Index(g.bands()));
      for (std::size_t k = 0; k < g.bands(); ++k) p[Eigen::Index(k)] = l.power[k * l.count + j] * l.length[j];
      power.push_back(p);
    }
  } else {
    const double el = cond.elevation_deg * kRefPi / 180, az_ = cond.azimuth_deg * kRefPi / 180;
    dirs.push_back({std::sin(el) * std::cos(az_), std::sin(el) * std::sin(az_), std::cos(el)});
    power.push_back(illuminant(cond.light, g.wavelengths));
  }
  Eigen::VectorXd radiance = Eigen::VectorXd::Zero(Eigen::Index(g.bands()));
  if (any_data) *any_data = false;
  for (std::size_t j = 0; j < dirs.size(); ++j) {
    const double ci = n.dot(dirs[j]);
    if (ci <= 0) continue;
    brdf::StdAngles a;
    a.theta_i = std::acos(std::min(1.0, ci));
    a.phi_i = std::atan2(b.dot(dirs[j]), t.dot(dirs[j]));
    a.theta_o = std::acos(std::min(1.0, n.dot(az)));
    a.phi_o = std::atan2(b.dot(az), t.dot(az));
    const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
    bool has = true;
    for (std::size_t k = 0; k < g.bands(); ++k) has &= g.brdf[k * brdf::kMerlCells + cell] >= 0;
    if (!has) continue;
    if (any_data) *any_data = true;
    for (std::size_t k = 0; k < g.bands(); ++k)
      radiance[Eigen::Index(k)] +=
          double(g.brdf[k * brdf::kMerlCells + cell]) * g.scale * power[j][Eigen::Index(k)] * ci;
  }
  return radiance;
}

/// What the separately written evaluation measures: pooled ΔE00 mean and 95th percentile and the worst
/// condition's mean.
struct ReferenceVerdict {
  double mean = 0, p95 = 0, worst = 0;
};

/// b against reference a under every condition of s, every disc pixel evaluated by brute_force.
inline ReferenceVerdict reference_verdict(const store::Grid& a, const store::Grid& b, const codec::LightingSuite& s) {
  const std::size_t n = s.size();
  std::vector<double> all;
  ReferenceVerdict v;
  for (std::size_t c = 0; c < s.conditions().size(); ++c) {
    const codec::SuiteCondition& cond = s.conditions()[c];
    std::vector<Eigen::Vector3d> xa, xb;
    std::vector<double> lum;
    for (std::size_t pix = 0; pix < n * n; ++pix) {
      const double px = 2 * (double(pix % n) + 0.5) / double(n) - 1, py = 1 - 2 * (double(pix / n) + 0.5) / double(n);
      if (px * px + py * py >= 1) continue;
      Eigen::Vector3d ax, ay, az;
      view_axes(cond.view, ax, ay, az);
      const Eigen::Vector3d nrm = px * ax + py * ay + std::sqrt(1 - px * px - py * py) * az;
      bool lit = false;
      if (cond.light == "environment") {
        for (std::size_t j = 0; j < s.environment_lights().count && !lit; ++j)
          lit = nrm.dot(s.environment_lights().dir[j]) > 0;
      } else {
        lit = nrm.dot(cond.direction) > 0;
      }
      if (!lit) continue;
      bool seen = false;
      const Eigen::VectorXd ra = brute_force(a, s, c, pix, &seen);
      if (!seen) continue;  // the reference has no data there: not compared
      xa.push_back(s.to_xyz() * ra);
      xb.push_back(s.to_xyz() * brute_force(b, s, c, pix));
      lum.push_back(xa.back().y());
    }
    // The light's white at the reference's 99th-percentile luminance.
    Eigen::Vector3d white;
    if (cond.light == "environment") {
      const auto& l = s.environment_lights();
      Eigen::VectorXd e = Eigen::VectorXd::Zero(Eigen::Index(a.bands()));
      Eigen::Vector3d vx, vy, vz;
      view_axes(cond.view, vx, vy, vz);
      for (std::size_t j = 0; j < l.count; ++j)
        if (l.dir[j].dot(vz) > 0)
          for (std::size_t k = 0; k < a.bands(); ++k)
            e[Eigen::Index(k)] += l.power[k * l.count + j] * l.length[j] * l.dir[j].dot(vz) / std::numbers::pi;
      white = s.to_xyz() * e;
    } else {
      white = s.to_xyz() * illuminant(cond.light, a.wavelengths) / std::numbers::pi;
    }
    std::vector<double> sorted = lum;
    std::sort(sorted.begin(), sorted.end());
    const double y = sorted.empty() ? 0 : sorted[std::size_t(std::ceil(0.99 * double(sorted.size()))) - 1];
    if (y > 0) white *= y / white.y();
    double sum = 0;
    for (std::size_t i = 0; i < xa.size(); ++i) {
      const double e = ciede2000(xyz_to_lab(xa[i], white), xyz_to_lab(xb[i], white));
      all.push_back(e);
      sum += e;
    }
    if (!xa.empty()) v.worst = std::max(v.worst, sum / double(xa.size()));
  }
  double sum = 0;
  for (const double e : all) sum += e;
  v.mean = all.empty() ? 0 : sum / double(all.size());
  std::sort(all.begin(), all.end());
  v.p95 = all.empty() ? 0 : all[std::size_t(std::ceil(0.95 * double(all.size()))) - 1];
  return v;
}

/// Whether v meets t: pooled mean and 95th percentile, and no condition's mean above t.condition_mean.
inline testing::AssertionResult meets_target(const ReferenceVerdict& v, const codec::SpcTarget& t) {
  if (v.mean <= t.de00_mean && v.p95 <= t.de00_p95 && v.worst <= t.condition_mean) return testing::AssertionSuccess();
  return testing::AssertionFailure() << "dE00 mean " << v.mean << ", p95 " << v.p95 << ", worst condition " << v.worst
                                     << " against " << t.de00_mean << ", " << t.de00_p95 << ", " << t.condition_mean;
}

}  // namespace specula::test
