#include "specula/codec/rgl_eval.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {

namespace {

using std::numbers::pi;

std::vector<float> channel_index(std::size_t n) {
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = float(i);
  return v;
}
}  // namespace

double rgl_theta_to_u(double theta) { return std::sqrt(std::max(theta, 0.0) * (2 / pi)); }
double rgl_u_to_theta(double u) { return u * u * (pi / 2); }
double rgl_phi_to_v(double phi) { return (phi + pi) / (2 * pi); }
double rgl_v_to_phi(double v) { return (2 * v - 1) * pi; }
double rgl_elevation(const Eigen::Vector3d& d) {
  const double dist = std::sqrt(d.x() * d.x() + d.y() * d.y() + (d.z() - 1) * (d.z() - 1));
  return 2 * std::asin(std::clamp(0.5 * dist, -1.0, 1.0));
}

RglEvaluator::RglEvaluator(const RglBsdf& b)
    : channels_(b.channels()),
      jacobian_(b.jacobian),
      ndf_(b.ndf, b.ndf_width, b.ndf_height, {}, false),
      sigma_(b.sigma, b.sigma_width, b.sigma_height, {}, false),
      vndf_(b.vndf, b.vndf_width, b.vndf_height, {b.phi_i, b.theta_i}, true),
      values_(b.values, b.resolution, b.resolution, {b.phi_i, b.theta_i, channel_index(b.channels())}, false) {}

double RglEvaluator::ndf(double u, double v) const { return ndf_.eval(u, v, {}); }
double RglEvaluator::sigma(double theta_i) const { return sigma_.eval(rgl_theta_to_u(theta_i), rgl_phi_to_v(0), {}); }

RglEvaluator::Query RglEvaluator::locate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  const Eigen::Vector3d m = (wi + wo).normalized();
  const double theta_i = rgl_elevation(wi), phi_i = std::atan2(wi.y(), wi.x());
  const double theta_m = rgl_elevation(m), phi_m = std::atan2(m.y(), m.x());
  const double u_m = rgl_theta_to_u(theta_m);
  double v_m = rgl_phi_to_v(phi_m - phi_i);
  v_m -= std::floor(v_m);
  Query q;
  q.params[0] = phi_i;
  q.params[1] = theta_i;
  q.s = vndf_.invert(u_m, v_m, q.params);
  q.factor = 1 / wo.z();
  if (jacobian_)
    q.factor *= ndf_.eval(u_m, v_m, {}) / (4 * sigma_.eval(rgl_theta_to_u(theta_i), rgl_phi_to_v(phi_i), {}));
  return q;
}

Eigen::Vector2d RglEvaluator::sample_point(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  const Query q = locate(wi, wo);
  return {q.s.x, q.s.y};
}

void RglEvaluator::eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const {
  if (out.size() != channels_)
    throw UsageError("RglEvaluator::eval: out holds " + std::to_string(out.size()) + " values, the material " +
                     std::to_string(channels_));
  std::fill(out.begin(), out.end(), 0.0);
  if (!(wi.z() > 0 && wo.z() > 0)) return;
  const Query q = locate(wi, wo);
  values_.eval_last(q.s.x, q.s.y, q.params, out);
  for (auto& v : out) v = std::max(0.0, v) * q.factor;
}

RglStencil RglEvaluator::stencil(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  RglStencil out;
  if (!(wi.z() > 0 && wo.z() > 0)) return out;
  const Query q = locate(wi, wo);
  // The value table's slices run over (theta_i, channel), channel fastest: channel 0 of each elevation.
  const WarpStencil w = values_.stencil(q.s.x, q.s.y, q.params, 2);
  const std::size_t per_slice = values_.width() * values_.height(), per_theta = per_slice * channels_;
  for (int k = 0; k < w.n; ++k) {
    const std::size_t i = w.index[std::size_t(k)], o = std::size_t(out.n);
    if (w.weight[std::size_t(k)] == 0) continue;
    out.theta[o] = std::uint32_t(i / per_theta);
    out.node[o] = std::uint32_t(i % per_slice);
    out.weight[o] = w.weight[std::size_t(k)] * q.factor;
    ++out.n;
  }
  return out;
}

std::vector<double> RglEvaluator::albedo(double theta_i, std::size_t n) const {
  const Eigen::Vector3d wi(std::sin(theta_i), 0, std::cos(theta_i));
  const double params[2] = {0, theta_i};
  std::vector<double> sum(channels_, 0.0), f(channels_);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < n; ++i) {
      const WarpPoint p = vndf_.sample((double(i) + 0.5) / double(n), (double(j) + 0.5) / double(n), params);
      const double theta_m = rgl_u_to_theta(p.x), phi_m = rgl_v_to_phi(p.y);
      const Eigen::Vector3d m(std::sin(theta_m) * std::cos(phi_m), std::sin(theta_m) * std::sin(phi_m),
                              std::cos(theta_m));
      const Eigen::Vector3d wo = 2 * wi.dot(m) * m - wi;
      if (!(wo.z() > 0) || !(wi.dot(m) > 0) || !(p.pdf > 0)) continue;
      // Density of wo: the square's density over the Jacobian of (u, v) -> m (2 pi^2 u sin theta_m) and of m -> wo.
      const double pdf = p.pdf / (std::max(2 * pi * pi * p.x * std::sin(theta_m), 1e-12) * 4 * wi.dot(m));
      eval(wi, wo.normalized(), f);
      for (std::size_t c = 0; c < channels_; ++c) sum[c] += f[c] * wo.z() / pdf;
    }
  for (auto& v : sum) v /= double(n * n);
  return sum;
}

void RglEvaluator::merl_cell(std::size_t cell, std::span<double> out) const {
  Eigen::Vector3d wi, wo;
  brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
  thread_local std::vector<double> g;  // one per thread: no allocation per cell of an import
  g.resize(channels_);
  eval(wi, wo, out);
  eval(wo, wi, g);
  const double a = wo.z(), b = wi.z();
  for (std::size_t ch = 0; ch < channels_; ++ch) out[ch] = (out[ch] * a + g[ch] * b) / (a + b);
}

std::vector<float> rgl_merl_values(const RglBsdf& bsdf) {
  const RglEvaluator e(bsdf);
  const std::size_t channels = e.channels(), per_h = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;
  std::vector<float> out(channels * brdf::kMerlCells, -1.0f);
  parallel_for(std::size_t(brdf::kMerlThetaH), [&](std::size_t h) {
    std::vector<double> f(channels);
    for (std::size_t k = 0; k < per_h; ++k) {
      const std::size_t cell = h * per_h + k;
      if (!brdf::merl_cell_valid(brdf::merl_cell(cell))) continue;
      e.merl_cell(cell, f);
      for (std::size_t ch = 0; ch < channels; ++ch) out[ch * brdf::kMerlCells + cell] = float(f[ch]);
    }
  });
  return out;
}

store::GridParameterisation rgl_parameterisation(const RglBsdf& b) {
  return {.phi_i = b.phi_i,
          .theta_i = b.theta_i,
          .ndf_width = b.ndf_width,
          .ndf_height = b.ndf_height,
          .ndf = b.ndf,
          .sigma_width = b.sigma_width,
          .sigma_height = b.sigma_height,
          .sigma = b.sigma,
          .vndf_width = b.vndf_width,
          .vndf_height = b.vndf_height,
          .vndf = b.vndf,
          .resolution = b.resolution,
          .description = b.description};
}

store::Grid rgl_to_grid(const RglBsdf& bsdf, const std::string& source) {
  if (bsdf.rgb) throw UsageError(source + ": an RGB RGL file has no spectra; uplift its RGB (rgl_to_merl) instead");
  store::Grid g;
  g.wavelengths = WavelengthGrid(std::vector<double>(bsdf.wavelengths.begin(), bsdf.wavelengths.end()), source);
  g.brdf = rgl_merl_values(bsdf);
  g.provenance.source_file = source;
  g.provenance.importer = "rgl-bsdf";
  g.parameterisation = rgl_parameterisation(bsdf);
  return g;
}

MerlBrdf rgl_to_merl(const RglBsdf& bsdf) {
  if (!bsdf.rgb) throw UsageError("rgl_to_merl: a spectral RGL file; use rgl_to_grid");
  const std::vector<float> v = rgl_merl_values(bsdf);
  MerlBrdf m;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    if (v[cell] < 0) continue;
    m.set(cell, Eigen::Vector3d(v[cell], v[brdf::kMerlCells + cell], v[2 * brdf::kMerlCells + cell]));
  }
  return m;
}

}  // namespace specula::codec
