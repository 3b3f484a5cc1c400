// The kd-tree's neighbour weightings (brdf_resample.h): their names, and each neighbour's normalised weight.
#include "specula/core/brdf_resample.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "specula/core/error.h"

namespace specula::brdf {
namespace {

// Wendland's C2 kernel, (1 - r)^4 (4 r + 1) for r = d / R < 1, else 0.
double wendland(double d2, double reach2) {
  const double r = std::sqrt(d2 / reach2), t = (1 - r) * (1 - r);
  return r >= 1 ? 0.0 : t * t * (4 * r + 1);
}

// The local linear fit's equivalent weights: the fit of values y_j by a + b . x_j (x_j = offset_j / R) minimising
// sum kernel_j (y_j - a - b . x_j)^2 predicts a = sum l_j y_j with l_j = kernel_j e1' A^-1 (1, x_j), A =
// sum kernel_j (1, x_j)(1, x_j)'. A relative ridge of 1e-6 on b keeps A invertible when the neighbours are
// coplanar (the slope across them is then 0); sum l_j = 1 for any ridge on b.
void local_linear(std::span<const double> kernel, std::span<const float> offsets, double reach2, std::span<double> l) {
  const double inv_r = 1 / std::sqrt(reach2);
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  double total = 0;
  for (std::size_t j = 0; j < kernel.size(); ++j) {
    const Eigen::Vector4d x(1, offsets[3 * j] * inv_r, offsets[3 * j + 1] * inv_r, offsets[3 * j + 2] * inv_r);
    a.noalias() += kernel[j] * x * x.transpose();
    total += kernel[j];
  }
  for (int d = 1; d < 4; ++d) a(d, d) += 1e-6 * total;
  const Eigen::Vector4d b = a.ldlt().solve(Eigen::Vector4d::UnitX());
  for (std::size_t j = 0; j < kernel.size(); ++j)
    l[j] = kernel[j] * (b[0] + inv_r * (b[1] * offsets[3 * j] + b[2] * offsets[3 * j + 1] + b[3] * offsets[3 * j + 2]));
}

}  // namespace

Weights parse_weights(std::string_view name) {
  if (name == "mean") return Weights::mean;
  if (name == "shepard") return Weights::shepard;
  if (name == "renka") return Weights::renka;
  if (name == "wendland") return Weights::wendland;
  if (name == "loess") return Weights::loess;
  throw UsageError("weights '" + std::string(name) +
                   "': use loess (local linear, smoothing), wendland (kernel, smoothing), renka (Franke-Little, "
                   "continuous), shepard (eqs 5.9-5.10) or mean");
}

std::string_view weights_name(Weights w) {
  switch (w) {
    case Weights::mean:
      return "mean";
    case Weights::shepard:
      return "shepard";
    case Weights::renka:
      return "renka";
    case Weights::wendland:
      return "wendland";
    case Weights::loess:
      return "loess";
  }
  return "?";
}

bool weights_have_reach(Weights w) { return w == Weights::renka || w == Weights::wendland || w == Weights::loess; }

void neighbour_weights(Weights w, double power, std::span<const float> dist2, std::span<float> out, double reach2,
                       std::span<const float> offsets) {
  const std::size_t n = dist2.size();
  if (out.size() != n) throw UsageError("neighbour_weights: out must have one weight per neighbour");
  if (w == Weights::loess && offsets.size() != 3 * n)
    throw UsageError("neighbour_weights: loess needs 3 offsets per neighbour");
  if (n == 0) return;
  // Raw weights in double, written to out only once normalised.
  // raw on Eigen's widest alignment, so that its packet loops below need no scalar head.
  thread_local std::vector<double, Eigen::aligned_allocator<double>> raw;
  thread_local std::vector<double> kernel;
  raw.assign(n, 1.0);
  std::size_t at_zero = 0;
  for (const float d : dist2) at_zero += d == 0;
  const bool smoothing = w == Weights::wendland || w == Weights::loess;
  if ((w == Weights::shepard || w == Weights::renka) && at_zero) {
    for (std::size_t j = 0; j < n; ++j) raw[j] = dist2[j] == 0 ? 1.0 : 0.0;
  } else if (w == Weights::shepard) {
    // Eigen's packets give the same correctly rounded square roots and quotients as one at a time.
    // The squares widened first: over the float map's cast Eigen falls back to one scalar sqrt and division at a
    // time.
    Eigen::Map<Eigen::ArrayXd, Eigen::AlignedMax> r(raw.data(), Eigen::Index(n));
    r = Eigen::Map<const Eigen::ArrayXf>(dist2.data(), Eigen::Index(n)).cast<double>();
    if (power == 1)
      r = r.sqrt().inverse();
    else if (power == 2)
      r = r.inverse();
    else
      for (std::size_t j = 0; j < n; ++j) raw[j] = std::pow(double(dist2[j]), -0.5 * power);
  } else if (w == Weights::renka || (smoothing && at_zero < n)) {
    // Renka: ((R - d) / (R d))^2 = (1/d - 1/R)^2; with no reach (R infinite) 1/d^2.
    const double inv_r = std::isfinite(reach2) ? 1 / std::sqrt(reach2) : 0.0;
    if (smoothing && !std::isfinite(reach2)) reach2 = 2.25 * double(*std::max_element(dist2.begin(), dist2.end()));
    bool any = false;
    for (std::size_t j = 0; j < n; ++j) {
      const double t = std::max(0.0, 1 / std::sqrt(double(dist2[j])) - inv_r);
      raw[j] = smoothing ? wendland(dist2[j], reach2) : t * t;
      any = any || raw[j] > 0;
    }
    // Every neighbour as far as the reach (ties): the nearest share the weight, as the limit from inside does.
    if (!any)
      for (std::size_t j = 0; j < n; ++j)
        raw[j] = dist2[j] == *std::min_element(dist2.begin(), dist2.end()) ? 1.0 : 0.0;
    else if (w == Weights::loess) {
      kernel.assign(raw.begin(), raw.end());
      local_linear(kernel, offsets, reach2, raw);
    }
  }
  double sum = 0;
  for (const double r : raw) sum += r;
  for (std::size_t j = 0; j < n; ++j) out[j] = float(raw[j] / sum);
}

}  // namespace specula::brdf
