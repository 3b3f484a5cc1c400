#include "specula/codec/rgl_export.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_fit.h"
#include "specula/codec/rgl_warp.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kQuadraturePerPatch = 8;

// Values on the MERL grid (channels x cells, channel slowest, negative: no data) times `scale`, interpolated
// trilinearly in index space (theta_h through MERL's square-root index, phi_d periodic with period pi) over the
// neighbours holding data.
class MerlField {
 public:
  MerlField(std::span<const float> values, std::size_t channels, double scale)
      : values_(values), channels_(channels), scale_(scale) {}
  std::size_t channels() const { return channels_; }
  std::span<const float> values() const { return values_; }
  double scale() const { return scale_; }

  // f at half/difference angles into out; false when no neighbour holds data.
  bool eval(double theta_h, double theta_d, double phi_d, std::span<double> out) const {
    if (phi_d < 0) phi_d += kPi;
    const double x[3] = {std::sqrt(std::clamp(theta_h, 0.0, kPi / 2) / (kPi / 2)) * brdf::kMerlThetaH - 0.5,
                         std::clamp(theta_d, 0.0, kPi / 2) / (kPi / 2) * brdf::kMerlThetaD - 0.5,
                         std::clamp(phi_d, 0.0, kPi) / kPi * brdf::kMerlPhiD - 0.5};
    const int n[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};
    int i0[3], i1[3];
    double w1[3];
    for (int d = 0; d < 3; ++d) {
      const double f = std::floor(x[d]);
      w1[d] = x[d] - f;
      i0[d] = int(f);
      i1[d] = i0[d] + 1;
      if (d == 2) {  // periodic
        i0[d] = (i0[d] % n[d] + n[d]) % n[d];
        i1[d] = (i1[d] % n[d] + n[d]) % n[d];
      } else {
        i0[d] = std::clamp(i0[d], 0, n[d] - 1);
        i1[d] = std::clamp(i1[d], 0, n[d] - 1);
      }
    }
    std::fill(out.begin(), out.end(), 0.0);
    double total = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const int a = corner & 1 ? i1[0] : i0[0], b = corner & 2 ? i1[1] : i0[1], c = corner & 4 ? i1[2] : i0[2];
      const double w =
          (corner & 1 ? w1[0] : 1 - w1[0]) * (corner & 2 ? w1[1] : 1 - w1[1]) * (corner & 4 ? w1[2] : 1 - w1[2]);
      const std::size_t cell = brdf::merl_index({a, b, c});
      if (w <= 0 || !has_data(cell)) continue;
      total += w;
      for (std::size_t ch = 0; ch < channels_; ++ch) out[ch] += w * values_[ch * brdf::kMerlCells + cell];
    }
    if (!(total > 0)) {
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::HalfDiff{theta_h, 0, theta_d, phi_d}));
      if (!has_data(cell)) return false;
      for (std::size_t ch = 0; ch < channels_; ++ch) out[ch] = values_[ch * brdf::kMerlCells + cell] * scale_;
      return true;
    }
    for (auto& v : out) v *= scale_ / total;
    return true;
  }

 private:
  bool has_data(std::size_t cell) const {
    for (std::size_t ch = 0; ch < channels_; ++ch)
      if (!(values_[ch * brdf::kMerlCells + cell] >= 0)) return false;
    return true;
  }
  std::span<const float> values_;
  std::size_t channels_;
  double scale_;
};

// Integral over phi of max(0, a + b cos(phi)), b >= 0.
double clipped_cosine_ring(double a, double b) {
  if (a >= b) return 2 * kPi * a;
  if (a <= -b) return 0;
  const double phi0 = std::acos(-a / b);
  return 2 * (a * phi0 + b * std::sin(phi0));
}

// Linear interpolation of node values at u in [0, 1].
double at_u(std::span<const double> nodes, double u) {
  const double x = std::clamp(u, 0.0, 1.0) * double(nodes.size() - 1);
  const std::size_t i = std::min(std::size_t(x), nodes.size() - 2);
  const double f = x - double(i);
  return (1 - f) * nodes[i] + f * nodes[i + 1];
}

void check(const RglExportSettings& s) {
  if (s.theta_i < 2 || s.resolution < 2 || s.ndf_nodes < 2 || s.vndf_resolution < 2)
    throw UsageError("RGL export: theta_i, resolution, ndf_nodes and vndf_resolution must be at least 2");
  if (!(s.vndf_floor >= 0 && s.vndf_floor <= 100)) throw UsageError("RGL export: vndf_floor must be in [0, 100]");
  if (!(s.vndf_uniform >= 0 && s.vndf_uniform <= 1)) throw UsageError("RGL export: vndf_uniform must be in [0, 1]");
  if (!(s.vndf_exponent > 0 && s.vndf_exponent <= 1)) throw UsageError("RGL export: vndf_exponent must be in (0, 1]");
  if (s.theta_i > 90 || s.resolution > 512 || s.ndf_nodes > 4096 || s.vndf_resolution > 1024)
    throw UsageError("RGL export: at most 90 theta_i, a 512 sample grid, 4096 ndf nodes and a 1024 vndf grid");
}

// Where a node's half vector reaches the horizon, D(m) -> 0 and f cos(theta_o) 4 sigma / D explodes (for models whose
// f grows at grazing angles); bilinear interpolation would carry that into every query between such a node and its
// neighbours. Values above kOutlier times a channel's 99th percentile are clamped there.
void clamp_outliers(RglBsdf& b, std::size_t channels) {
  constexpr double kOutlier = 8;
  const std::size_t T = b.theta_i.size(), R2 = b.resolution * b.resolution;
  for (std::size_t c = 0; c < channels; ++c) {
    std::vector<float> v;
    for (std::size_t t = 0; t < T; ++t)
      v.insert(v.end(), b.values.begin() + std::ptrdiff_t((t * channels + c) * R2),
               b.values.begin() + std::ptrdiff_t((t * channels + c + 1) * R2));
    auto p99 = v.begin() + std::ptrdiff_t(v.size() * 99 / 100);
    std::nth_element(v.begin(), p99, v.end());
    const float cap = float(kOutlier) * std::max(*p99, 0.0f);
    if (!(cap > 0)) continue;
    for (std::size_t t = 0; t < T; ++t)
      for (std::size_t k = 0; k < R2; ++k) {
        float& x = b.values[(t * channels + c) * R2 + k];
        x = std::min(x, cap);
      }
  }
}

// The luminance of the stored values, with a tiny floor under each incident direction's so that the renderers can
// normalise it as a density.
void set_luminance(RglBsdf& b, std::size_t channels, std::span<const double> lum_weights) {
  const std::size_t T = b.theta_i.size(), R2 = b.resolution * b.resolution;
  b.luminance.assign(T * R2, 0.0f);
  for (std::size_t t = 0; t < T; ++t) {
    float* lum = b.luminance.data() + t * R2;
    for (std::size_t k = 0; k < R2; ++k) {
      double y = 0;
      for (std::size_t c = 0; c < channels; ++c) y += lum_weights[c] * b.values[(t * channels + c) * R2 + k];
      lum[k] = float(std::max(y, 0.0));
    }
    const float top = *std::max_element(lum, lum + R2);
    const float floor = top > 0 ? top * 1e-6f : 1.0f;
    for (std::size_t i = 0; i < R2; ++i) lum[i] = std::max(lum[i], floor);
  }
}

// The vndf table of one incident direction (RglExportSettings::vndf_floor, vndf_uniform) into out (V x V).
void vndf_slice(const Warp2D& ndf_table, const Eigen::Vector3d& wi, const RglExportSettings& s, std::span<float> out,
                std::size_t V) {
  std::vector<double> dens(V * V), vis(V * V);
  double dsum = 0, vsum = 0;
  const double d0 = std::max(ndf_table.eval(0, 0, {}), 1e-300);
  for (std::size_t y = 0; y < V; ++y)
    for (std::size_t x = 0; x < V; ++x) {
      const double u = double(x) / double(V - 1), theta_m = rgl_u_to_theta(u);
      const Eigen::Vector3d m = brdf::direction(theta_m, rgl_v_to_phi(double(y) / double(V - 1)));
      const double d = d0 * std::pow(std::max(ndf_table.eval(u, 0, {}), 0.0) / d0, s.vndf_exponent);
      dens[y * V + x] = (d + s.vndf_floor / kPi) * std::max(0.0, wi.dot(m)) * 2 * kPi * kPi * u * std::sin(theta_m);
      vis[y * V + x] = wi.dot(m) > 0 ? 1.0 : 0.0;
      dsum += dens[y * V + x];
      vsum += vis[y * V + x];
    }
  for (std::size_t k = 0; k < V * V; ++k)
    out[k] =
        float((1 - s.vndf_uniform) * dens[k] / std::max(dsum, 1e-300) + s.vndf_uniform * vis[k] / std::max(vsum, 1.0));
}

// The ndf and sigma tables (D from the retro-reflection of `field`, sigma(0) = 1) and theta_i into b.
void microfacet_tables(const MerlField& field, std::span<const double> lum_weights, const RglExportSettings& s,
                       RglBsdf& b) {
  const RglMicrofacet mf = rgl_microfacet(field.values(), field.channels(), field.scale(), lum_weights, s);
  const std::size_t N = mf.ndf.size();
  b.ndf_width = b.sigma_width = N;
  b.ndf_height = b.sigma_height = 2;
  for (int row = 0; row < 2; ++row)
    for (std::size_t k = 0; k < N; ++k) {
      b.ndf.push_back(float(mf.ndf[k]));
      b.sigma.push_back(float(mf.sigma[k]));
    }
  b.theta_i = rgl_theta_i(mf.sigma, s.theta_i);
}

// The vndf tables of the estimated parameterisation (RglExportSettings::vndf_*), one per theta_i of b.
void estimate_vndf(const RglExportSettings& s, RglBsdf& b) {
  const std::size_t V = s.vndf_resolution, T = b.theta_i.size();
  const Warp2D ndf_table(b.ndf, b.ndf_width, b.ndf_height, {}, false);
  b.vndf_width = b.vndf_height = V;
  b.vndf.resize(T * V * V);
  parallel_for(T, [&](std::size_t t) {
    vndf_slice(ndf_table, brdf::direction(b.theta_i[t], 0), s, {b.vndf.data() + t * V * V, V * V}, V);
  });
}

// The source file's tables into b as they are, except a vndf with more than `vndf_side` nodes per side: resampled to
// at most that by resample_density (the published files' 128^2 would make a 31-band file 1.58 MB; docs/brdf.md).
void source_tables(const store::GridParameterisation& p, std::size_t vndf_side, RglBsdf& b) {
  b.phi_i = p.phi_i;
  b.theta_i = p.theta_i;
  b.ndf_width = p.ndf_width;
  b.ndf_height = p.ndf_height;
  b.ndf = p.ndf;
  b.sigma_width = p.sigma_width;
  b.sigma_height = p.sigma_height;
  b.sigma = p.sigma;
  b.vndf_width = std::min(p.vndf_width, vndf_side);
  b.vndf_height = std::min(p.vndf_height, vndf_side);
  b.vndf = resample_density(p.vndf, p.vndf_width, p.vndf_height, b.vndf_width, b.vndf_height);
  b.resolution = p.resolution;
}

// Per incident elevation the point samples f cos(theta_o) 4 sigma / D at the nodes of the sample square warped by b's
// vndf table; returns the nodes whose wo lies above the horizon (theta_i x rows x columns).
std::vector<std::uint8_t> sample_nodes(const MerlField& field, RglBsdf& b) {
  const std::size_t C = field.channels(), R = b.resolution, T = b.theta_i.size();
  const std::size_t VW = b.vndf_width, VH = b.vndf_height;
  // The tables as the renderers read them (float, bilinear).
  const Warp2D ndf_table(b.ndf, b.ndf_width, b.ndf_height, {}, false);
  const Warp2D sigma_table(b.sigma, b.sigma_width, b.sigma_height, {}, false);
  b.values.assign(T * C * R * R, 0.0f);
  std::vector<std::uint8_t> valid(T * R * R, 0);
  parallel_for(T, [&](std::size_t t) {
    const double theta_i = b.theta_i[t];
    const Eigen::Vector3d wi = brdf::direction(theta_i, 0);
    const Warp2D warp({b.vndf.data() + t * VW * VH, VW * VH}, VW, VH, {}, true);
    const double sigma_i = sigma_table.eval(rgl_theta_to_u(theta_i), rgl_phi_to_v(0), {});
    std::vector<double> fv(C);
    for (std::size_t j = 0; j < R; ++j)
      for (std::size_t i = 0; i < R; ++i) {
        const WarpPoint p = warp.sample(double(i) / double(R - 1), double(j) / double(R - 1), {});
        const Eigen::Vector3d m = brdf::direction(rgl_u_to_theta(p.x), rgl_v_to_phi(p.y));
        const Eigen::Vector3d wo = 2 * wi.dot(m) * m - wi;
        const double d = ndf_table.eval(p.x, p.y, {});
        if (!(wo.z() > 0) || !(wi.dot(m) > 0) || !(d > 0)) continue;
        const brdf::HalfDiff hd = brdf::half_diff(wi, wo.normalized());
        if (!field.eval(hd.theta_h, hd.theta_d, hd.phi_d, fv)) continue;
        valid[(t * R + j) * R + i] = 1;
        const double k = wo.z() * 4 * sigma_i / d;
        for (std::size_t c = 0; c < C; ++c) b.values[((t * C + c) * R + j) * R + i] = float(fv[c] * k);
      }
  });
  return valid;
}

// The file of `field`: spectral on `wavelengths`, or RGB when they are empty; on `source` when
// rgl_parameterisation_used says so.
RglBsdf build(const MerlField& field, std::span<const double> lum_weights, std::vector<float> wavelengths,
              const RglExportSettings& settings, const store::GridParameterisation* source) {
  const bool on_source = rgl_parameterisation_used(source, settings) == RglParameterisation::source;
  RglExportSettings s = settings;
  if (s.theta_i == 0) s.theta_i = source ? source->theta_i.size() : 8;
  if (s.resolution == 0) s.resolution = source ? source->resolution : 32;
  check(s);
  const std::size_t C = field.channels();
  RglBsdf b;
  b.description = s.description.empty() ? "specula export" : s.description;
  b.rgb = wavelengths.empty();
  b.wavelengths = std::move(wavelengths);
  if (on_source) {
    source_tables(*source, s.vndf_resolution, b);
  } else {
    microfacet_tables(field, lum_weights, s, b);
    b.resolution = s.resolution;
    estimate_vndf(s, b);
  }
  const std::vector<std::uint8_t> valid = sample_nodes(field, b);
  clamp_outliers(b, C);
  if (s.least_squares) {
    rgl_fit_values(b, field.values(), field.scale(), lum_weights, s.fit);
    clamp_outliers(b, C);
  }
  set_luminance(b, C, lum_weights);
  b.valid.assign((valid.size() + 7) / 8, 0);
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (valid[i]) b.valid[i / 8] |= std::uint8_t(0x80u >> (i % 8));
  return b;
}

}  // namespace

const char* rgl_parameterisation_name(RglParameterisation p) {
  switch (p) {
    case RglParameterisation::automatic:
      return "auto";
    case RglParameterisation::source:
      return "source";
    case RglParameterisation::estimate:
      return "estimate";
  }
  return "?";
}

RglParameterisation parse_rgl_parameterisation(const std::string& name) {
  for (const auto p : {RglParameterisation::automatic, RglParameterisation::source, RglParameterisation::estimate})
    if (name == rgl_parameterisation_name(p)) return p;
  throw UsageError("RGL export: parameterisation '" + name + "'; use auto, source or estimate");
}

RglParameterisation rgl_parameterisation_used(const store::GridParameterisation* source, const RglExportSettings& s) {
  if (s.parameterisation == RglParameterisation::estimate) return RglParameterisation::estimate;
  const bool own_size = source && (s.theta_i == 0 || s.theta_i == source->theta_i.size()) &&
                        (s.resolution == 0 || s.resolution == source->resolution);
  if (s.parameterisation == RglParameterisation::automatic)
    return own_size ? RglParameterisation::source : RglParameterisation::estimate;
  if (!source)
    throw UsageError(
        "RGL export: the source parameterisation was asked, but the grid carries none (only grids "
        "imported from a .bsdf keep it)");
  if (!own_size)
    throw UsageError("RGL export: the source parameterisation has " + std::to_string(source->theta_i.size()) +
                     " theta_i and a " + std::to_string(source->resolution) + "^2 sample grid; " +
                     std::to_string(s.theta_i) + " theta_i and " + std::to_string(s.resolution) + "^2 were asked");
  return RglParameterisation::source;
}

std::vector<double> rgl_sigma(std::span<const double> ndf, std::span<const double> theta) {
  const std::size_t N = ndf.size();
  if (N < 2) throw UsageError("rgl_sigma: at least 2 ndf nodes");
  // Midpoint rule in u within each of the N - 1 patches (D is linear in u there); d theta = pi u du.
  const std::size_t Q = (N - 1) * kQuadraturePerPatch;
  const double du = 1.0 / double(Q);
  std::vector<double> out(theta.size(), 0.0);
  for (std::size_t q = 0; q < Q; ++q) {
    const double u = (double(q) + 0.5) * du, tm = rgl_u_to_theta(u);
    const double w = at_u(ndf, u) * std::sin(tm) * kPi * u * du;
    if (w == 0) continue;
    for (std::size_t k = 0; k < theta.size(); ++k)
      out[k] += w * clipped_cosine_ring(std::cos(theta[k]) * std::cos(tm), std::sin(theta[k]) * std::sin(tm));
  }
  return out;
}

std::vector<double> rgl_ndf_from_retro(std::span<const double> retro, std::size_t iterations) {
  const std::size_t N = retro.size();
  std::vector<double> theta(N), d(N);
  for (std::size_t k = 0; k < N; ++k) theta[k] = rgl_u_to_theta(double(k) / double(N - 1));
  bool any = false;
  for (std::size_t k = 0; k < N; ++k) {
    d[k] = std::max(retro[k], 0.0) * std::cos(theta[k]);
    any = any || d[k] > 0;
  }
  if (!any) std::fill(d.begin(), d.end(), 1 / kPi);  // black retro-reflection: a cosine distribution
  const double zero = 0;
  for (std::size_t it = 0; it <= iterations; ++it) {
    const double norm = rgl_sigma(d, {&zero, 1})[0];
    for (auto& v : d) v /= norm;
    if (it == iterations || !any) break;
    const std::vector<double> sigma = rgl_sigma(d, theta);
    for (std::size_t k = 0; k < N; ++k) d[k] = std::max(retro[k], 0.0) * std::cos(theta[k]) * sigma[k];
  }
  return d;
}

RglMicrofacet rgl_microfacet(std::span<const float> values, std::size_t channels, double scale,
                             std::span<const double> lum_weights, const RglExportSettings& s) {
  check(s);
  if (channels == 0 || values.size() != channels * brdf::kMerlCells || lum_weights.size() != channels)
    throw UsageError("rgl_microfacet: the BRDF and the luminance weights disagree in size");
  const MerlField field(values, channels, scale);
  const std::size_t N = s.ndf_nodes;
  // Retro-reflection (theta_d = 0) at the ndf nodes, as luminance.
  std::vector<double> retro(N), f(channels), node_theta(N);
  for (std::size_t k = 0; k < N; ++k) {
    node_theta[k] = rgl_u_to_theta(double(k) / double(N - 1));
    double y = 0;
    if (field.eval(node_theta[k], 0, 0, f))
      for (std::size_t c = 0; c < channels; ++c) y += lum_weights[c] * f[c];
    retro[k] = std::max(y, 0.0);
  }
  RglMicrofacet mf{rgl_ndf_from_retro(retro, s.power_iterations), {}};
  mf.sigma = rgl_sigma(mf.ndf, node_theta);
  const double sigma0 = mf.sigma[0];
  for (auto& v : mf.sigma) v /= sigma0;
  for (auto& v : mf.ndf) v /= sigma0;
  return mf;
}

std::vector<float> rgl_vndf(std::span<const double> ndf, double theta_i, const RglExportSettings& s) {
  check(s);
  if (ndf.size() < 2) throw UsageError("rgl_vndf: at least 2 ndf nodes");
  std::vector<float> rows(2 * ndf.size());
  for (std::size_t k = 0; k < rows.size(); ++k) rows[k] = float(ndf[k % ndf.size()]);
  const std::size_t V = s.vndf_resolution;
  std::vector<float> out(V * V);
  vndf_slice(Warp2D(rows, ndf.size(), 2, {}, false), brdf::direction(theta_i, 0), s, out, V);
  return out;
}

std::vector<float> rgl_theta_i(std::span<const double> sigma, std::size_t n) {
  if (n < 2 || sigma.size() < 2) throw UsageError("rgl_theta_i: at least 2 elevations and 2 sigma nodes");
  std::vector<float> theta(n);
  theta[0] = 0;
  theta[n - 1] = float(kPi / 2);
  const double s0 = sigma.front(), s1 = sigma.back();
  for (std::size_t j = 1; j + 1 < n; ++j) {
    const double target = s0 - double(j) / double(n - 1) * (s0 - s1);
    double lo = 0, hi = 1;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (at_u(sigma, mid) > target ? lo : hi) = mid;
    }
    theta[j] = std::max(float(rgl_u_to_theta(0.5 * (lo + hi))), std::nextafter(theta[j - 1], 2.0f));
  }
  for (std::size_t j = n - 1; j-- > 1;) theta[j] = std::min(theta[j], std::nextafter(theta[j + 1], 0.0f));
  return theta;
}

RglBsdf export_rgl(const store::Grid& grid, const RglExportSettings& settings) {
  if (grid.brdf.size() != grid.bands() * brdf::kMerlCells)
    throw UsageError("RGL export: the grid holds " + std::to_string(grid.brdf.size()) +
                     " values, not bands x 90 x 90 x 180");
  const Eigen::Matrix<double, 3, Eigen::Dynamic> w = rgb_weights(grid.wavelengths, illuminant("D65", grid.wavelengths));
  const Eigen::RowVectorXd y = Eigen::RowVector3d(0.2126, 0.7152, 0.0722) * w;
  const std::vector<double> lum(y.data(), y.data() + y.size());
  return build(MerlField(grid.brdf, grid.bands(), grid.scale), lum,
               std::vector<float>(grid.wavelengths.values().begin(), grid.wavelengths.values().end()), settings,
               grid.parameterisation ? &*grid.parameterisation : nullptr);
}

RglBsdf export_rgl(const MerlBrdf& brdf, const RglExportSettings& settings, const store::GridParameterisation* source) {
  std::vector<float> v(3 * brdf::kMerlCells);
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
      const double x = brdf.stored(int(c), cell);
      v[c * brdf::kMerlCells + cell] = x < 0 ? -1.0f : float(x * kMerlScale[c]);
    }
  const double lum[3] = {0.2126, 0.7152, 0.0722};
  return build(MerlField(v, 3, 1.0), lum, {}, settings, source);
}

}  // namespace specula::codec
