#include "codec/environment.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "codec/spectral_grid.h"
#include "codec/uplift.h"
#include "core/brdf_geometry.h"
#include "core/cie.h"
#include "core/colour.h"
#include "core/error.h"
#include "store/io/exr.h"

namespace specula::codec {
namespace {

using std::numbers::pi;
constexpr std::size_t kDirsW = 32, kDirsH = 16;  // the environment's directions used for shading

Eigen::Vector3d lat_long_direction(double theta, double phi) {
  return {std::sin(theta) * std::sin(phi), std::cos(theta), std::sin(theta) * std::cos(phi)};
}

// The environment averaged over kDirsH x kDirsW regions (weighted by solid angle): each region's centre
// direction and its radiance times solid angle.
struct Lights {
  std::vector<Eigen::Vector3d> dir;
  Eigen::MatrixXd power;  // bands x directions: L * d_omega
};

Lights downsample(const Environment& env) {
  const std::size_t b = env.wavelengths.size();
  Lights l;
  l.power = Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(kDirsW * kDirsH));
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(Eigen::Index(kDirsW * kDirsH));
  for (std::size_t y = 0; y < env.height; ++y) {
    const double theta = pi * (double(y) + 0.5) / double(env.height);
    const double d_omega = std::sin(theta) * (pi / double(env.height)) * (2 * pi / double(env.width));
    const std::size_t ry = y * kDirsH / env.height;
    for (std::size_t x = 0; x < env.width; ++x) {
      const std::size_t j = ry * kDirsW + x * kDirsW / env.width;
      const float* px = env.radiance.data() + (y * env.width + x) * b;
      for (std::size_t k = 0; k < b; ++k) l.power(Eigen::Index(k), Eigen::Index(j)) += d_omega * px[k];
      weight[Eigen::Index(j)] += d_omega;
    }
  }
  for (std::size_t ry = 0; ry < kDirsH; ++ry)
    for (std::size_t rx = 0; rx < kDirsW; ++rx)
      l.dir.push_back(lat_long_direction(pi * (double(ry) + 0.5) / kDirsH, 2 * pi * (double(rx) + 0.5) / kDirsW));
  return l;
}

void check_radiance(const std::vector<float>& v, const std::string& label) {
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!(v[i] >= 0) || !std::isfinite(v[i]))
      throw InputError(label + ": environment value " + std::to_string(i) + " is " + std::to_string(v[i]) +
                       "; radiance must be finite and non-negative");
}

}  // namespace

Environment default_environment(const WavelengthGrid& grid) {
  Environment e;
  e.wavelengths = grid;
  e.width = 128;
  e.height = 64;
  const std::size_t b = grid.size();
  Eigen::VectorXd sky = daylight(12000, grid), sun = daylight(5500, grid), ground_light = daylight(6500, grid);
  sky /= sky.maxCoeff();
  sun /= sun.maxCoeff();
  ground_light /= ground_light.maxCoeff();
  Eigen::VectorXd ground(static_cast<Eigen::Index>(b));  // a green-brown soil: rising towards the red, a green bump
  for (std::size_t k = 0; k < b; ++k) {
    const double l = grid[k];
    ground[Eigen::Index(k)] = 0.08 + 0.17 / (1 + std::exp(-(l - 600) / 30)) + 0.06 * std::exp(-0.5 * std::pow((l - 545) / 25, 2));
  }
  e.radiance.resize(e.width * e.height * b);
  for (std::size_t y = 0; y < e.height; ++y) {
    const double theta = pi * (double(y) + 0.5) / double(e.height);
    const double up = std::cos(theta);
    for (std::size_t x = 0; x < e.width; ++x) {
      float* px = e.radiance.data() + (y * e.width + x) * b;
      for (std::size_t k = 0; k < b; ++k)
        px[k] = float(up > 0 ? 0.12 * (0.4 + 0.6 * up) * sky[Eigen::Index(k)]
                             : 0.25 * ground[Eigen::Index(k)] * ground_light[Eigen::Index(k)]);
    }
  }
  e.sun_direction = Eigen::Vector3d(-0.45, 0.6, 0.66).normalized();
  e.sun_irradiance = 1.2 * sun;
  e.description = "built-in: 12000 K daylight sky, green-brown ground, 5500 K sun";
  return e;
}

Environment read_environment(const std::filesystem::path& path, const WavelengthGrid& grid) {
  const std::string label = path.string();
  Environment e;
  e.wavelengths = grid;
  e.description = label;
  const std::size_t b = grid.size();
  if (store::exr_is_spectral(path)) {
    const store::Cube cube = store::read_spectral_exr(path);
    const Eigen::MatrixXd r = resample_matrix(cube.wavelengths, grid, label);
    e.width = cube.width;
    e.height = cube.height;
    e.radiance.resize(e.width * e.height * b);
    for (std::size_t p = 0; p < e.width * e.height; ++p) {
      const Eigen::Map<const Eigen::VectorXf> s(cube.data.data() + p * cube.bands, Eigen::Index(cube.bands));
      Eigen::Map<Eigen::VectorXf>(e.radiance.data() + p * b, Eigen::Index(b)) = (r * s.cast<double>()).cast<float>();
    }
    check_radiance(e.radiance, label);
    return e;
  }
  std::size_t w = 0, h = 0;
  const std::vector<float> rgb = store::read_exr_rgb(path, w, h);
  check_radiance(rgb, label);
  const Uplift up(rgb_weights(grid, Eigen::VectorXd::Ones(Eigen::Index(b))), kDefaultUpliftAlpha);
  // Uplift the 32 x 16 averages, not every pixel: shading only sees those, and Appendix A is per colour.
  e.width = kDirsW;
  e.height = kDirsH;
  std::vector<double> sum(3 * kDirsW * kDirsH, 0), weight(kDirsW * kDirsH, 0);
  for (std::size_t y = 0; y < h; ++y) {
    const double s = std::sin(pi * (double(y) + 0.5) / double(h));
    for (std::size_t x = 0; x < w; ++x) {
      const std::size_t j = (y * kDirsH / h) * kDirsW + x * kDirsW / w;
      for (std::size_t c = 0; c < 3; ++c) sum[3 * j + c] += s * rgb[3 * (y * w + x) + c];
      weight[j] += s;
    }
  }
  e.radiance.resize(kDirsW * kDirsH * b);
  Eigen::VectorXd x(static_cast<Eigen::Index>(b));
  UpliftCache cache;
  for (std::size_t j = 0; j < kDirsW * kDirsH; ++j) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    if (weight[j] > 0) c = Eigen::Vector3d(sum[3 * j], sum[3 * j + 1], sum[3 * j + 2]) / weight[j];
    up.nonnegative(c, x, &cache);
    for (std::size_t k = 0; k < b; ++k) e.radiance[j * b + k] = float(x[Eigen::Index(k)]);
  }
  return e;
}

SphereRenders render_spheres(const std::vector<const store::Grid*>& grids, const Environment& env, std::size_t size) {
  if (size < 8 || size > 4096) throw UsageError("sphere size " + std::to_string(size) + ": give 8 to 4096 pixels");
  const std::size_t b = env.wavelengths.size();
  if (env.radiance.size() != env.width * env.height * b || env.width == 0)
    throw UsageError("render: environment buffers do not match its size");
  for (const auto* g : grids) {
    if (!g->wavelengths.approx_equal(env.wavelengths))
      throw InputError("a grid has " + g->wavelengths.describe() + ", the environment " + env.wavelengths.describe() +
                       "; render on the grid's own wavelengths");
    if (g->brdf.size() != b * brdf::kMerlCells) throw UsageError("render: grid values do not match bands x 90 x 90 x 180");
  }
  const Lights lights = downsample(env);
  const bool sun = env.sun_irradiance.size() == Eigen::Index(b);
  const SpectrumToXyz to_xyz(env.wavelengths, SpectrumKind::radiance, Eigen::VectorXd::Ones(Eigen::Index(b)));
  const Eigen::Matrix<double, 3, Eigen::Dynamic>& w = to_xyz.weights();
  SphereRenders out;
  out.size = size;
  out.covered.assign(size * size, 0);
  out.xyz.assign(grids.size(), std::vector<float>(3 * size * size, 0.0f));
  // White: a Lambertian surface of albedo 1 facing the viewer, f = 1 / pi.
  Eigen::VectorXd white_l = Eigen::VectorXd::Zero(Eigen::Index(b));
  for (std::size_t j = 0; j < lights.dir.size(); ++j)
    if (lights.dir[j].z() > 0) white_l += lights.power.col(Eigen::Index(j)) * lights.dir[j].z() / pi;
  if (sun && env.sun_direction.z() > 0) white_l += env.sun_irradiance * env.sun_direction.z() / pi;
  out.white = w * white_l;
#pragma omp parallel
  {
    Eigen::MatrixXd l(static_cast<Eigen::Index>(b), static_cast<Eigen::Index>(grids.size()));
#pragma omp for schedule(dynamic, 4)
    for (long long py = 0; py < static_cast<long long>(size); ++py) {
      for (std::size_t px = 0; px < size; ++px) {
        const double x = 2 * (double(px) + 0.5) / double(size) - 1, y = 1 - 2 * (double(py) + 0.5) / double(size);
        if (x * x + y * y >= 1) continue;
        const Eigen::Vector3d n(x, y, std::sqrt(1 - x * x - y * y));
        // Any tangent frame will do: the grids are isotropic.
        const Eigen::Vector3d t = (std::abs(n.y()) < 0.9 ? Eigen::Vector3d::UnitY().cross(n) : Eigen::Vector3d::UnitX().cross(n)).normalized();
        const Eigen::Vector3d s = n.cross(t);
        auto local = [&](const Eigen::Vector3d& d) { return Eigen::Vector3d(d.dot(t), d.dot(s), d.dot(n)); };
        const Eigen::Vector3d wo = local(Eigen::Vector3d::UnitZ());
        l.setZero();
        auto add = [&](const Eigen::Vector3d& world, const double* power, std::ptrdiff_t stride) {
          const Eigen::Vector3d wi = local(world);
          if (wi.z() <= 0 || wo.z() <= 0) return;
          const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::half_diff(wi, wo)));
          for (std::size_t g = 0; g < grids.size(); ++g) {
            const store::Grid& grid = *grids[g];
            for (std::size_t k = 0; k < b; ++k) {
              const float f = grid.brdf[k * brdf::kMerlCells + cell];
              if (f > 0) l(Eigen::Index(k), Eigen::Index(g)) += double(f) * grid.scale * power[std::ptrdiff_t(k) * stride] * wi.z();
            }
          }
        };
        for (std::size_t j = 0; j < lights.dir.size(); ++j)
          add(lights.dir[j], lights.power.data() + j * b, 1);
        if (sun) add(env.sun_direction, env.sun_irradiance.data(), 1);
        const std::size_t p = std::size_t(py) * size + px;
        out.covered[p] = 1;
        for (std::size_t g = 0; g < grids.size(); ++g) {
          const Eigen::Vector3d xyz = w * l.col(Eigen::Index(g));
          for (std::size_t c = 0; c < 3; ++c) out.xyz[g][3 * p + c] = float(xyz[Eigen::Index(c)]);
        }
      }
    }
  }
  return out;
}

}  // namespace specula::codec
