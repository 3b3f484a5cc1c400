#include "specula/core/brdf_models.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::brdf {
namespace {

using std::numbers::pi;

void check(const WavelengthGrid& grid, const Eigen::VectorXd& v, const char* model, const char* what, double lo,
           bool lo_open, double hi) {
  if (std::size_t(v.size()) != grid.size())
    throw UsageError(std::string(model) + ": " + what + " has " + std::to_string(v.size()) + " values for " +
                     std::to_string(grid.size()) + " bands; give one per band");
  for (Eigen::Index b = 0; b < v.size(); ++b) {
    const double x = v[b];
    if (!std::isfinite(x) || x < lo || (lo_open && x == lo) || x > hi)
      throw UsageError(std::string(model) + ": " + what + " at " + num(grid[std::size_t(b)]) + " nm is " + num(x) +
                       "; it must be " + (lo_open ? "> " : ">= ") + num(lo) +
                       (std::isinf(hi) ? std::string() : " and <= " + num(hi)));
  }
}

constexpr double kInf = std::numeric_limits<double>::infinity();

void check_out(std::span<double> out, std::size_t bands) {
  if (out.size() != bands)
    throw UsageError("BRDF evaluation: output has " + std::to_string(out.size()) + " values for " +
                     std::to_string(bands) + " bands");
}

// Checks out's size; zeroes it and returns false when either direction is below the horizon.
bool prepare(std::span<double> out, std::size_t bands, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  check_out(out, bands);
  if (wi.z() > 0 && wo.z() > 0) return true;
  std::fill(out.begin(), out.end(), 0.0);
  return false;
}

}  // namespace

SpectralModel::SpectralModel(WavelengthGrid grid) : grid_(std::move(grid)) {
  if (grid_.empty()) throw UsageError("BRDF model: the wavelength grid is empty; give at least one band");
}

void SpectralModel::eval(const StdAngles& a, std::span<double> out) const {
  eval(direction(a.theta_i, a.phi_i), direction(a.theta_o, a.phi_o), out);
}

double fresnel_dielectric(double theta, double eta) {
  const double s = std::sin(theta);
  if (s >= eta) return 1.0;
  if (theta < 1e-7) return ((eta - 1) / (eta + 1)) * ((eta - 1) / (eta + 1));
  const double t = std::asin(s / eta);
  const double a = std::sin(t - theta) / std::sin(t + theta);
  const double b = std::tan(theta - t) / std::tan(theta + t);
  return 0.5 * (a * a + b * b);
}

Lambertian::Lambertian(WavelengthGrid grid, Eigen::VectorXd rho)
    : SpectralModel(std::move(grid)), rho_(std::move(rho)) {
  check(grid_, rho_, "Lambertian", "rho", 0, false, 1);
}

void Lambertian::eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const {
  check_out(out, bands());
  const bool above = wi.z() > 0 && wo.z() > 0;
  for (std::size_t b = 0; b < out.size(); ++b) out[b] = above ? rho_[Eigen::Index(b)] / pi : 0.0;
}

TorranceSparrow::TorranceSparrow(WavelengthGrid grid, Eigen::VectorXd m, Eigen::VectorXd eta, Eigen::VectorXd rho_d)
    : SpectralModel(std::move(grid)), m_(std::move(m)), eta_(std::move(eta)), rho_d_(std::move(rho_d)) {
  check(grid_, m_, "Torrance-Sparrow", "m", 0, true, kInf);
  check(grid_, eta_, "Torrance-Sparrow", "eta", 0, true, kInf);
  check(grid_, rho_d_, "Torrance-Sparrow", "rho_d", 0, false, 1);
}

void TorranceSparrow::eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const {
  if (!prepare(out, bands(), wi, wo)) return;
  const double ci = wi.z(), co = wo.z();
  const Eigen::Vector3d h = (wi + wo).normalized();
  const double ch = h.z(), cd = std::min(1.0, wi.dot(h));
  const double theta_d = std::acos(cd);
  const double tan2 = (1 - ch * ch) / (ch * ch);
  const double g = std::min({1.0, 2 * ch * ci / cd, 2 * ch * co / cd});
  for (std::size_t b = 0; b < out.size(); ++b) {
    const auto k = Eigen::Index(b);
    const double m2 = m_[k] * m_[k];
    const double d = std::exp(-tan2 / m2) / (4 * m2 * ch * ch * ch * ch);
    out[b] = rho_d_[k] / pi + d * g * fresnel_dielectric(theta_d, eta_[k]) / (pi * ci * co);
  }
}

Ward::Ward(WavelengthGrid grid, Eigen::VectorXd rho_d, Eigen::VectorXd rho_s, Eigen::VectorXd alpha)
    : SpectralModel(std::move(grid)), rho_d_(std::move(rho_d)), rho_s_(std::move(rho_s)), alpha_(std::move(alpha)) {
  check(grid_, rho_d_, "Ward", "rho_d", 0, false, 1);
  check(grid_, rho_s_, "Ward", "rho_s", 0, false, kInf);
  check(grid_, alpha_, "Ward", "alpha", 0, true, kInf);
}

void Ward::eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const {
  if (!prepare(out, bands(), wi, wo)) return;
  const double ci = wi.z(), co = wo.z();
  const Eigen::Vector3d h = (wi + wo).normalized();
  const double ch = h.z();
  const double tan2 = (1 - ch * ch) / (ch * ch);
  const double root = std::sqrt(ci * co);
  for (std::size_t b = 0; b < out.size(); ++b) {
    const auto k = Eigen::Index(b);
    const double a2 = alpha_[k] * alpha_[k];
    out[b] = rho_d_[k] / pi + rho_s_[k] * std::exp(-tan2 / a2) / (4 * pi * a2 * root);
  }
}

void evaluate_at(const SpectralModel& model, std::span<const double> angles, std::span<float> values) {
  const std::size_t b = model.bands();
  if (angles.size() % 4 != 0 || values.size() != angles.size() / 4 * b)
    throw UsageError("evaluate_at: needs n x 4 angles and n x " + std::to_string(b) + " values, got " +
                     std::to_string(angles.size()) + " angles and " + std::to_string(values.size()) + " values");
  std::vector<double> f(b);
  for (std::size_t n = 0; n < angles.size() / 4; ++n) {
    model.eval(StdAngles{angles[4 * n], angles[4 * n + 1], angles[4 * n + 2], angles[4 * n + 3]}, f);
    for (std::size_t k = 0; k < b; ++k) values[n * b + k] = float(f[k]);
  }
}

void evaluate_grid(const SpectralModel& model, std::span<float> grid) {
  const std::size_t b = model.bands();
  if (grid.size() != b * kMerlCells)
    throw UsageError("evaluate_grid: the grid holds " + std::to_string(grid.size()) + " values; " + std::to_string(b) +
                     " bands need " + std::to_string(b * kMerlCells));
  std::vector<double> f(b);
  Eigen::Vector3d wi, wo;
  for (std::size_t idx = 0; idx < kMerlCells; ++idx) {
    const MerlCell c = merl_cell(idx);
    directions(merl_cell_centre(c), wi, wo);
    if (wi.z() > 0 && wo.z() > 0) {
      model.eval(wi, wo, f);
      for (std::size_t k = 0; k < b; ++k) grid[k * kMerlCells + idx] = float(f[k]);
    } else {
      for (std::size_t k = 0; k < b; ++k) grid[k * kMerlCells + idx] = -1.0f;
    }
  }
}

}  // namespace specula::brdf
