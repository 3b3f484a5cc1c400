#include "specula/codec/environment.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>
#include <sstream>

#include "specula/codec/spectral_grid.h"
#include "specula/codec/uplift.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/store/io/exr.h"

namespace specula::codec {
namespace {

using std::numbers::pi;

// Exact solid angle and first moment (the integral of d over the pixel) of each row and column factor of a
// lat-long map: pixel (x, y) has solid angle row.omega[y] * col.dphi[x] and moment
// (row.s2[y] * col.dcos[x], row.dsin2[y] * col.dphi[x], row.s2[y] * col.dsin[x]).
struct LatLongGeometry {
  std::vector<double> omega, s2, dsin2;  // per row: cos t0 - cos t1, int sin^2, (sin^2 t1 - sin^2 t0) / 2
  std::vector<double> dphi, dcos, dsin;  // per column: p1 - p0, cos p0 - cos p1, sin p1 - sin p0
  LatLongGeometry(std::size_t width, std::size_t height) {
    for (std::size_t y = 0; y < height; ++y) {
      const double t0 = pi * double(y) / double(height), t1 = pi * double(y + 1) / double(height);
      omega.push_back(std::cos(t0) - std::cos(t1));
      s2.push_back((t1 - t0) / 2 - (std::sin(2 * t1) - std::sin(2 * t0)) / 4);
      dsin2.push_back((std::sin(t1) * std::sin(t1) - std::sin(t0) * std::sin(t0)) / 2);
    }
    for (std::size_t x = 0; x < width; ++x) {
      const double p0 = 2 * pi * double(x) / double(width), p1 = 2 * pi * double(x + 1) / double(width);
      dphi.push_back(p1 - p0);
      dcos.push_back(std::cos(p0) - std::cos(p1));
      dsin.push_back(std::sin(p1) - std::sin(p0));
    }
  }
  double solid_angle(std::size_t x, std::size_t y) const { return omega[y] * dphi[x]; }
  Eigen::Vector3d moment(std::size_t x, std::size_t y) const {
    return {s2[y] * dcos[x], dsin2[y] * dphi[x], s2[y] * dsin[x]};
  }
};

// A surface of normal n sees a region light's mean cosine n . m (exact when the region lies wholly above its horizon).
using Lights = EnvironmentLights;

Lights make_lights(const Environment& env, std::size_t regions_w = kEnvironmentRegionsW,
                   std::size_t regions_h = kEnvironmentRegionsH) {
  const std::size_t b = env.wavelengths.size();
  const std::size_t rw = std::min(regions_w, env.width), rh = std::min(regions_h, env.height);
  const LatLongGeometry geo(env.width, env.height);
  std::vector<double> omega(rw * rh, 0.0);
  std::vector<Eigen::Vector3d> moment(rw * rh, Eigen::Vector3d::Zero());
  Eigen::MatrixXd power = Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(rw * rh));
  for (std::size_t y = 0; y < env.height; ++y)
    for (std::size_t x = 0; x < env.width; ++x) {
      const std::size_t j = (y * rh / env.height) * rw + x * rw / env.width;
      const double d_omega = geo.solid_angle(x, y);
      omega[j] += d_omega;
      moment[j] += geo.moment(x, y);
      const float* px = env.radiance.data() + (y * env.width + x) * b;
      for (std::size_t k = 0; k < b; ++k) power(Eigen::Index(k), Eigen::Index(j)) += d_omega * double(px[k]);
    }
  std::vector<std::size_t> keep;
  for (std::size_t j = 0; j < rw * rh; ++j)
    if (power.col(Eigen::Index(j)).maxCoeff() > 0) keep.push_back(j);
  const bool sun = env.sun_irradiance.size() == Eigen::Index(b) && env.sun_irradiance.maxCoeff() > 0;
  Lights l;
  l.count = keep.size() + (sun ? 1 : 0);
  l.power.resize(b * l.count);
  for (std::size_t i = 0; i < keep.size(); ++i) {
    const Eigen::Vector3d m = moment[keep[i]] / omega[keep[i]];
    l.dir.push_back(m.normalized());
    l.length.push_back(m.norm());
    for (std::size_t k = 0; k < b; ++k) l.power[k * l.count + i] = power(Eigen::Index(k), Eigen::Index(keep[i]));
  }
  if (sun) {
    l.dir.push_back(env.sun_direction.normalized());
    l.length.push_back(1.0);
    for (std::size_t k = 0; k < b; ++k) l.power[k * l.count + keep.size()] = env.sun_irradiance[Eigen::Index(k)];
  }
  return l;
}

std::string pixel_name(std::size_t index, std::size_t per_pixel, std::size_t width) {
  const std::size_t p = index / per_pixel;
  return "pixel (" + std::to_string(p % width) + ", " + std::to_string(p / width) + ")";
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The smallest factor dividing both sides that brings a map to at most 256 x 128 pixels (1 if none does).
std::size_t reduction_factor(std::size_t w, std::size_t h) {
  for (std::size_t f = std::max<std::size_t>({1, (w + 255) / 256, (h + 127) / 128}); f <= std::min(w, h); ++f)
    if (w % f == 0 && h % f == 0) return f;
  return 1;
}

}  // namespace

EnvironmentLights environment_lights(const Environment& env, std::size_t regions_w, std::size_t regions_h) {
  if (regions_w < 1 || regions_h < 1) throw UsageError("environment lights: give at least 1 x 1 regions");
  if (env.width == 0 || env.height == 0 || env.radiance.size() != env.width * env.height * env.wavelengths.size())
    throw UsageError("environment lights: environment buffers do not match its size");
  return make_lights(env, regions_w, regions_h);
}

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
    ground[Eigen::Index(k)] =
        0.08 + 0.17 / (1 + std::exp(-(l - 600) / 30)) + 0.06 * std::exp(-0.5 * std::pow((l - 545) / 25, 2));
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

Environment uniform_environment(const WavelengthGrid& grid, const Eigen::VectorXd& radiance) {
  if (radiance.size() != Eigen::Index(grid.size()))
    throw UsageError("uniform_environment: " + std::to_string(radiance.size()) + " radiance values for " +
                     std::to_string(grid.size()) + " bands");
  if (!(radiance.minCoeff() >= 0) || !radiance.allFinite())
    throw UsageError("uniform_environment: radiance must be finite and non-negative");
  Environment e;
  e.wavelengths = grid;
  e.width = 2 * kEnvironmentRegionsW;
  e.height = 2 * kEnvironmentRegionsH;
  e.radiance.reserve(e.width * e.height * grid.size());
  for (std::size_t p = 0; p < e.width * e.height; ++p)
    for (Eigen::Index k = 0; k < radiance.size(); ++k) e.radiance.push_back(float(radiance[k]));
  e.sun_irradiance.resize(0);
  e.description = "uniform";
  return e;
}

Environment read_environment(const std::filesystem::path& path, const WavelengthGrid& grid) {
  const std::string label = path.string();
  Environment e;
  e.wavelengths = grid;
  e.sun_irradiance.resize(0);
  e.description = label;
  const std::size_t b = grid.size();
  if (store::exr_is_spectral(path)) {
    const store::Cube cube = store::read_spectral_exr(path);
    if (cube.units == "reflectance")
      throw InputError(label + ": holds reflectance (T.* channels); an environment is emission, S0.* channels");
    for (std::size_t i = 0; i < cube.data.size(); ++i)
      if (!(cube.data[i] >= 0) || !std::isfinite(cube.data[i]))
        throw InputError(label + ": " + pixel_name(i, cube.bands, cube.width) + " at " +
                         num(cube.wavelengths[i % cube.bands]) + " nm is " + num(cube.data[i]) +
                         "; radiance must be finite and non-negative");
    const Eigen::MatrixXd r = resample_matrix(cube.wavelengths, grid, label);
    e.width = cube.width;
    e.height = cube.height;
    e.radiance.resize(e.width * e.height * b);
    for (std::size_t p = 0; p < e.width * e.height; ++p) {
      const Eigen::Map<const Eigen::VectorXf> s(cube.data.data() + p * cube.bands, Eigen::Index(cube.bands));
      Eigen::Map<Eigen::VectorXf>(e.radiance.data() + p * b, Eigen::Index(b)) = (r * s.cast<double>()).cast<float>();
    }
    return e;
  }
  std::size_t w = 0, h = 0;
  const std::vector<float> rgb = store::read_exr_rgb(path, w, h);  // refuses non-finite values
  for (std::size_t i = 0; i < rgb.size(); ++i)
    if (!(rgb[i] >= 0))
      throw InputError(label + ": " + pixel_name(i, 3, w) + " has " + "RGB"[i % 3] + " = " + num(rgb[i]) +
                       "; radiance must be non-negative");
  const Uplift up(rgb_weights(grid, Eigen::VectorXd::Ones(Eigen::Index(b))), kDefaultUpliftAlpha);
  // Every pixel uplifted, then box-filtered by f x f with exact solid-angle weights: the integral over each
  // output pixel is the integral of the uplifted full-resolution map, at a fraction of its memory.
  const std::size_t f = reduction_factor(w, h);
  e.width = w / f;
  e.height = h / f;
  e.radiance.assign(e.width * e.height * b, 0.0f);
  const LatLongGeometry geo(w, h);
  struct RowState {
    Eigen::VectorXd x, sum;
  };
  parallel_for(
      e.height,
      [&] {
        return RowState{Eigen::VectorXd(Eigen::Index(b)), Eigen::VectorXd(Eigen::Index(b))};
      },
      [&](std::size_t oy, RowState& st) {
        Eigen::VectorXd &x = st.x, &sum = st.sum;
        UpliftCache cache;  // one per output row, so the result does not depend on the thread count
        for (std::size_t ox = 0; ox < e.width; ++ox) {
          sum.setZero();
          double omega = 0;
          for (std::size_t y = std::size_t(oy) * f; y < (std::size_t(oy) + 1) * f; ++y)
            for (std::size_t xx = ox * f; xx < (ox + 1) * f; ++xx) {
              const float* c = rgb.data() + 3 * (y * w + xx);
              up.nonnegative(Eigen::Vector3d(c[0], c[1], c[2]), x, &cache);
              sum += geo.solid_angle(xx, y) * x;
              omega += geo.solid_angle(xx, y);
            }
          for (std::size_t k = 0; k < b; ++k)
            e.radiance[(std::size_t(oy) * e.width + ox) * b + k] = float(sum[Eigen::Index(k)] / omega);
        }
      });
  return e;
}

namespace {

// One (pixel, light) pair of a block of image rows.
struct Pair {
  std::uint32_t cell, pixel;  // pixel within the block
  std::uint32_t light;
  float weight;  // the light's mean cosine
};

// The one sphere-and-lights loop of both renderers: checks, lights, white, blocks of image rows and every
// (pixel, light) pair's cell (per row, pixels left to right, lights in order); shade(row_pairs, rows, pixels,
// lights, acc) adds each of `count` BRDFs' band values times light power times weight into acc (count x bands x
// pixels, zeroed), and scale(g) is BRDF g's scale.
template <class Shade, class Scale>
SphereRenders render_with(std::size_t count, const Environment& env, std::size_t size, Shade&& shade, Scale&& scale) {
  if (size < 8 || size > 4096) throw UsageError("sphere size " + std::to_string(size) + ": give 8 to 4096 pixels");
  const std::size_t b = env.wavelengths.size();
  if (env.width == 0 || env.height == 0 || env.radiance.size() != env.width * env.height * b)
    throw UsageError("render: environment buffers do not match its size");
  const Lights lights = make_lights(env);
  const std::size_t nl = lights.count;
  const SpectrumToXyz to_xyz(env.wavelengths, SpectrumKind::radiance, Eigen::VectorXd::Ones(Eigen::Index(b)));
  const Eigen::Matrix<double, 3, Eigen::Dynamic>& w = to_xyz.weights();
  SphereRenders out;
  out.size = size;
  out.covered.assign(size * size, 0);
  out.xyz.assign(count, std::vector<float>(3 * size * size, 0.0f));
  // White: a Lambertian surface of albedo 1 (f = 1 / pi) facing the viewer, by the same quadrature.
  Eigen::VectorXd white_l = Eigen::VectorXd::Zero(Eigen::Index(b));
  for (std::size_t j = 0; j < nl; ++j)
    if (lights.dir[j].z() > 0)
      for (std::size_t k = 0; k < b; ++k)
        white_l[Eigen::Index(k)] += lights.power[k * nl + j] * lights.length[j] * lights.dir[j].z() / pi;
  out.white = w * white_l;
  const std::size_t rows_per_block = std::clamp<std::size_t>((std::size_t(1) << 21) / (size * (nl / 2 + 1)), 1, size);
  std::vector<std::vector<Pair>> row_pairs(rows_per_block);
  std::vector<double> acc;
  for (std::size_t row0 = 0; row0 < size; row0 += rows_per_block) {
    check_interrupt();
    const std::size_t rows = std::min(rows_per_block, size - row0), pixels = rows * size;
    parallel_for(rows, [&](std::size_t r) {
      std::vector<Pair>& pairs = row_pairs[std::size_t(r)];
      pairs.clear();
      std::vector<float> wis, wos;  // the row's directions, for merl_indices' vectorised lookup
      const std::size_t py = row0 + std::size_t(r);
      for (std::size_t px = 0; px < size; ++px) {
        const double x = 2 * (double(px) + 0.5) / double(size) - 1, y = 1 - 2 * (double(py) + 0.5) / double(size);
        if (x * x + y * y >= 1) continue;
        out.covered[py * size + px] = 1;
        const Eigen::Vector3d n(x, y, std::sqrt(1 - x * x - y * y));
        // Any tangent frame will do: the BRDFs are isotropic.
        const Eigen::Vector3d t =
            (std::abs(n.y()) < 0.9 ? Eigen::Vector3d::UnitY().cross(n) : Eigen::Vector3d::UnitX().cross(n))
                .normalized();
        const Eigen::Vector3d s = n.cross(t);
        const Eigen::Vector3d wo(t.z(), s.z(), n.z());
        for (std::size_t j = 0; j < nl; ++j) {
          const Eigen::Vector3d& d = lights.dir[j];
          const double c = n.dot(d);
          if (c <= 0) continue;
          const float wi[3] = {float(t.dot(d)), float(s.dot(d)), float(c)};
          wis.insert(wis.end(), wi, wi + 3);
          wos.insert(wos.end(), {float(wo.x()), float(wo.y()), float(wo.z())});
          pairs.push_back(
              {0, std::uint32_t(std::size_t(r) * size + px), std::uint32_t(j), float(c * lights.length[j])});
        }
      }
      std::vector<std::uint32_t> cells(pairs.size());
      merl_indices(wis, wos, cells);
      for (std::size_t i = 0; i < pairs.size(); ++i) pairs[i].cell = cells[i];
    });
    acc.assign(count * b * pixels, 0.0);
    shade(std::span<const std::vector<Pair>>(row_pairs.data(), rows), pixels, lights, acc);
    for (std::size_t g = 0; g < count; ++g)
      for (std::size_t i = 0; i < pixels; ++i) {
        const std::size_t pix = row0 * size + i;
        if (!out.covered[pix]) continue;
        Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
        for (std::size_t k = 0; k < b; ++k) xyz += w.col(Eigen::Index(k)) * acc[(g * b + k) * pixels + i];
        for (std::size_t c = 0; c < 3; ++c) out.xyz[g][3 * pix + c] = float(scale(g) * xyz[Eigen::Index(c)]);
      }
  }
  check_interrupt();
  return out;
}

void check_wavelengths(const WavelengthGrid& brdf, const Environment& env, const char* what) {
  if (!brdf.approx_equal(env.wavelengths))
    throw InputError(std::string("a ") + what + " has " + brdf.describe() + ", the environment " +
                     env.wavelengths.describe() + "; render on the " + what + "'s own wavelengths");
}

}  // namespace

SphereRenders render_spheres(const std::vector<const store::Grid*>& grids, const Environment& env, std::size_t size) {
  const std::size_t b = env.wavelengths.size();
  for (const auto* g : grids) {
    check_wavelengths(g->wavelengths, env, "grid");
    if (g->brdf.size() != b * brdf::kMerlCells)
      throw UsageError("render: grid values do not match bands x 90 x 90 x 180");
  }
  // Per block, the pairs sorted by cell (counting sort on buckets of 256 cells, stable), so that each band plane
  // of a grid is swept once per block in increasing address order. Each pixel's sum runs in that fixed order, so
  // the result does not depend on the thread count.
  constexpr std::size_t kBucketShift = 8, kBuckets = (brdf::kMerlCells >> kBucketShift) + 1, kChunk = 4096;
  std::vector<Pair> sorted;
  std::vector<std::uint32_t> start(kBuckets + 1);
  auto shade = [&](std::span<const std::vector<Pair>> row_pairs, std::size_t pixels, const Lights& lights,
                   std::vector<double>& acc) {
    const std::size_t nl = lights.count;
    std::fill(start.begin(), start.end(), 0u);
    std::size_t total = 0;
    for (const auto& pairs : row_pairs) {
      total += pairs.size();
      for (const Pair& p : pairs) ++start[(p.cell >> kBucketShift) + 1];
    }
    for (std::size_t i = 1; i <= kBuckets; ++i) start[i] += start[i - 1];
    sorted.resize(total);
    for (const auto& pairs : row_pairs)
      for (const Pair& p : pairs) sorted[start[p.cell >> kBucketShift]++] = p;
    // Each thread owns a fixed share of the (grid, band) planes and walks the pairs in cache-sized chunks,
    // every chunk through all its planes, so the pairs come from memory once per thread, not once per plane.
    parallel_shares(grids.size() * b, [&](std::size_t task_first, std::size_t task_last) {
      for (std::size_t c0 = 0; c0 < sorted.size(); c0 += kChunk) {
        const Pair* first = sorted.data() + c0;
        const Pair* last = sorted.data() + std::min(sorted.size(), c0 + kChunk);
        for (std::size_t gk = task_first; gk < task_last; ++gk) {
          const float* plane = grids[gk / b]->brdf.data() + (gk % b) * brdf::kMerlCells;
          const double* power = lights.power.data() + (gk % b) * nl;
          double* a = acc.data() + gk * pixels;
          for (const Pair* p = first; p != last; ++p)
            a[p->pixel] += double(std::max(plane[p->cell], 0.0f)) * power[p->light] * double(p->weight);
        }
      }
    });
  };
  return render_with(grids.size(), env, size, shade, [&](std::size_t g) { return grids[g]->scale; });
}

SphereRenders render_spheres(std::span<const SpcBrdf* const> brdfs, const Environment& env, std::size_t size) {
  const std::size_t b = env.wavelengths.size();
  for (const auto* f : brdfs) check_wavelengths(f->wavelengths(), env, "coded BRDF");
  // Each row's pairs in their order (pixel, then light), every pair's cell expanded from its k coefficients:
  // rows on any thread, each pixel summed in one fixed order, so the result does not depend on the thread count.
  auto shade = [&](std::span<const std::vector<Pair>> row_pairs, std::size_t pixels, const Lights& lights,
                   std::vector<double>& acc) {
    const std::size_t nl = lights.count;
    parallel_for(
        row_pairs.size(), [&] { return std::vector<float>(b); },
        [&](std::size_t r, std::vector<float>& f) {
          for (std::size_t g = 0; g < brdfs.size(); ++g)
            for (const Pair& p : row_pairs[r]) {
              brdfs[g]->evaluate_cell(p.cell, f);
              double* a = acc.data() + g * b * pixels + p.pixel;
              const double* power = lights.power.data() + p.light;
              for (std::size_t k = 0; k < b; ++k) a[k * pixels] += double(f[k]) * power[k * nl] * double(p.weight);
            }
        });
  };
  return render_with(brdfs.size(), env, size, shade, [](std::size_t) { return 1.0; });
}

}  // namespace specula::codec
