#include "specula/codec/render.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "specula/codec/environment.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/error.h"
#include "specula/core/preview.h"

namespace specula::codec {

namespace {

// The one directional-light sphere loop: rgb(angles) is the linear RGB BRDF (1/sr) at the pixel's standard angles.
template <class Rgb>
SphereImage render_with(std::size_t size, const Eigen::Vector3d& light, Rgb&& rgb) {
  if (size == 0 || size > 16384) throw UsageError("render: size " + std::to_string(size) + " must be 1-16384 pixels");
  if (!(light.norm() > 0) || !light.allFinite())
    throw UsageError("render: the light direction must be a non-zero vector");
  const Eigen::Vector3d l = light.normalized(), v(0, 0, 1);
  SphereImage img;
  img.size = size;
  img.linear.assign(3 * size * size, 0.0f);
  img.covered.assign(size * size, 0);
  for (std::size_t row = 0; row < size; ++row)
    for (std::size_t col = 0; col < size; ++col) {
      const double x = (double(col) + 0.5) / double(size) * 2 - 1, y = 1 - (double(row) + 0.5) / double(size) * 2;
      const double r2 = x * x + y * y;
      if (r2 >= 1) continue;
      const std::size_t p = row * size + col;
      img.covered[p] = 1;
      const Eigen::Vector3d n(x, y, std::sqrt(1 - r2));
      // Orthonormal tangent frame (Duff et al. 2017); the BRDF is isotropic, so its orientation is free.
      const double sign = std::copysign(1.0, n.z()), a = -1 / (sign + n.z()), b = n.x() * n.y() * a;
      const Eigen::Vector3d t(1 + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
      const Eigen::Vector3d s(b, sign + n.y() * n.y() * a, -n.y());
      const Eigen::Vector3d wi(l.dot(t), l.dot(s), l.dot(n)), wo(v.dot(t), v.dot(s), v.dot(n));
      if (wi.z() <= 0 || wo.z() <= 0) continue;
      const double ti = std::acos(std::min(1.0, wi.z())), to = std::acos(std::min(1.0, wo.z()));
      const Eigen::Vector3d f = rgb(brdf::StdAngles{ti, std::atan2(wi.y(), wi.x()), to, std::atan2(wo.y(), wo.x())});
      for (int c = 0; c < 3; ++c)
        img.linear[3 * p + std::size_t(c)] = float(std::numbers::pi * std::max(0.0, f[c]) * wi.z());
    }
  return img;
}

}  // namespace

SphereImage render_sphere(const MerlBrdf& merl, std::size_t size, const Eigen::Vector3d& light) {
  return render_with(size, light, [&](const brdf::StdAngles& a) { return merl.lookup(a); });
}

SphereImage render_sphere(const SpcBrdf& coded, const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights,
                          std::size_t size, const Eigen::Vector3d& light) {
  if (std::size_t(weights.cols()) != coded.bands())
    throw UsageError("render: RGB weights have " + std::to_string(weights.cols()) + " columns for a BRDF of " +
                     std::to_string(coded.bands()) + " bands; give one per band");
  std::vector<float> f(coded.bands());
  return render_with(size, light, [&](const brdf::StdAngles& a) {
    coded.evaluate_cell(brdf::merl_index(brdf::merl_cell(a)), f);
    const Eigen::Vector3d rgb =
        weights * Eigen::Map<const Eigen::VectorXf>(f.data(), Eigen::Index(f.size())).cast<double>();
    return rgb.cwiseMax(0.0).eval();
  });
}

SphereImage render_sphere(const store::Grid& grid, const Eigen::VectorXd& illuminant, std::size_t size,
                          const Eigen::Vector3d& light) {
  return render_sphere(grid_to_merl(grid, rgb_weights(grid.wavelengths, illuminant)).brdf, size, light);
}

void linear_srgb(const SphereRenders& renders, std::string_view lighting, std::size_t index, std::span<double> out) {
  if (!(renders.white.y() > 0))
    throw InputError(std::string(lighting) + " sends no light to a surface facing the viewer; nothing maps to white");
  if (out.size() != 3 * renders.covered.size())
    throw UsageError("linear_srgb: " + std::to_string(out.size()) + " values for " +
                     std::to_string(renders.covered.size()) + " pixels; give 3 per pixel");
  const Eigen::Matrix3d m = rendering_to_linear_srgb(renders.white);
  const std::vector<float>& xyz = renders.xyz.at(index);
  for (std::size_t i = 0; i < renders.covered.size(); ++i) {
    const Eigen::Vector3d c = m * Eigen::Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    for (std::size_t k = 0; k < 3; ++k) out[3 * i + k] = c[Eigen::Index(k)];
  }
}

SphereImage linear_srgb(const SphereRenders& renders, std::string_view lighting, std::size_t index) {
  std::vector<double> linear(3 * renders.covered.size());
  linear_srgb(renders, lighting, index, linear);
  SphereImage img{renders.size, std::vector<float>(linear.size()), renders.covered};
  std::transform(linear.begin(), linear.end(), img.linear.begin(), [](double v) { return float(v); });
  return img;
}

}  // namespace specula::codec
