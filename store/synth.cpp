// Synthetic natural-scene radiance images: a stand-in for Chakrabarti & Zickler's database (Braley 2012,
// §7.2-7.3) so benchmarks and the demo can reach ~59 million spectra with no outside data.
//
// Scene model (per image; every random choice comes from a PRNG seeded by (seed, index) alone):
//  * Reflectances: a palette of 20-60 smooth spectra evaluated analytically at the grid wavelengths:
//      - generic: squashed (logistic into [0.02, 0.95]) sum of a tilt, 1-3 broad Gaussians (sigma 35-120 nm)
//        and 0-2 logistic edges, like painted or mineral surfaces;
//      - foliage: low blue, green bump near 550 nm, chlorophyll trough near 670 nm, red edge at 695-725 nm
//        (some dry/yellowed variants with the bump shifted to longer wavelengths);
//      - soil / bark / wood: monotonically rising, sometimes with an iron-oxide shoulder at 530-620 nm;
//      - near-neutral: stone, concrete (flat with a slight tilt).
//  * Layout: a power (weighted Voronoi) diagram of 12-40 cells, each a material with its own surface
//    orientation, plus 0-6 elliptical objects painted on top. Within a region the radiance is modulated
//    only by scalar factors (texture, shading, grain), so the spectral shape of a region is constant.
//  * Texture: per region a low-amplitude (1-8 %) oriented cosine pattern (period 3-30 px) from a per-image
//    set of four, times 0.5-2 % per-pixel multiplicative grain.
//  * Illumination: sun = CIE daylight of CCT 4000-12000 K, image intensity log-uniform over a factor 10;
//    sky = CIE daylight of CCT 10000-20000 K (never below the sun's + 1000 K) at 10-30 % of the sun at
//    560 nm. Lit pixels receive shade * (sun + sky), shadowed pixels shade * sky only (0-3 soft-edged
//    elliptical cast shadows and sometimes a straight-edged one, e.g. a building). Lambertian shading is the
//    region's cos(incidence) in [0.35, 1] times a slowly varying field (three random low-frequency
//    plane waves), so surfaces curve gently.
//  * Sensor: additive Gaussian read noise of std noise * m (m = the image's mean noise-free radiance) plus
//    signal-dependent shot noise, total std noise * m * sqrt(1 + 4 L / m); values may go slightly negative.
//  * Mask: 0-3 rectangles per image marked invalid (0), like the masked human subjects of §7.2; the pixels
//    under them still hold scene radiance.
// Radiance = reflectance * illuminant / 100 * intensity (daylight is 100 at 560 nm), so a white surface
// facing a bright sun gives about 1-3.
//
// Speed: everything spectral is precomputed per palette entry (reflectance x sun, reflectance x sky); a
// pixel costs two multiply-adds per band plus noise, in fixed 16-float packets. Region labels use the
// convexity of power-diagram cells: where the four corners of an 8x8 block share a cell, the whole block
// does. Normal deviates come from a 4096-entry inverse-CDF table (unit variance) indexed by 12-bit slices
// of eight interleaved xoshiro256** streams. Rows are generated in parallel, each with its own generators
// seeded from (image seed, row), so the result does not depend on the thread count. The cube's pages are
// pre-faulted from all threads (Linux), since first-touch faults of a fresh cube cost as much as the rest.
#include "specula/store/synth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/store/detail/synth_random.h"

namespace specula::store {
using namespace synth_detail;
namespace {

constexpr double kPi = std::numbers::pi;

double logistic(double t) { return 1.0 / (1.0 + std::exp(-t)); }
double gauss(double x, double mu, double sigma) {
  const double d = (x - mu) / sigma;
  return std::exp(-0.5 * d * d);
}

/// One smooth reflectance spectrum at the grid wavelengths, values in [0.02, 0.95].
std::vector<double> make_reflectance(Rng& rng, std::span<const double> nm) {
  const std::size_t n = nm.size();
  std::vector<double> r(n);
  const double family = rng.uniform();
  if (family < 0.38) {  // generic: squashed sum of broad bumps and edges
    const double level = rng.uniform(-2.5, 0.8);
    const double tilt = rng.uniform(-1.2, 1.2);
    const int bumps = rng.integer(1, 3), edges = rng.integer(0, 2);
    std::vector<std::array<double, 3>> bump(static_cast<std::size_t>(bumps)), edge(static_cast<std::size_t>(edges));
    for (auto& b : bump) b = {rng.uniform(-1.8, 1.8), rng.uniform(380, 780), rng.uniform(35, 120)};
    for (auto& e : edge) e = {rng.uniform(-1.5, 1.5), rng.uniform(430, 700), rng.uniform(12, 40)};
    for (std::size_t i = 0; i < n; ++i) {
      const double l = nm[i];
      double f = level + tilt * (l - 580) / 200;
      for (const auto& b : bump) f += b[0] * gauss(l, b[1], b[2]);
      for (const auto& e : edge) f += e[0] * logistic((l - e[1]) / e[2]);
      r[i] = 0.02 + 0.93 * logistic(f);
    }
    return r;
  }
  if (family < 0.70) {  // foliage (some dry / yellowed)
    const bool dry = rng.chance(0.25);
    const double base = rng.uniform(0.025, 0.06);
    const double green = dry ? rng.uniform(0.08, 0.25) : rng.uniform(0.03, 0.12);
    const double green_mu = dry ? rng.uniform(575, 620) : rng.uniform(540, 560);
    const double green_w = dry ? rng.uniform(45, 90) : rng.uniform(25, 40);
    const double nir = rng.uniform(0.25, 0.55);
    const double edge_mu = rng.uniform(695, 725), edge_w = rng.uniform(9, 16);
    const double trough = rng.uniform(0.3, 0.8);
    for (std::size_t i = 0; i < n; ++i) {
      const double l = nm[i];
      double v = base + green * gauss(l, green_mu, green_w);
      if (dry) v += 0.5 * green * logistic((l - 560) / 25);
      v *= 1.0 - trough * gauss(l, 672, 18);  // chlorophyll-a absorption
      v += nir * logistic((l - edge_mu) / edge_w);
      r[i] = std::clamp(v, 0.02, 0.95);
    }
    return r;
  }
  if (family < 0.93) {  // soil, bark, wood: rising
    const double a = rng.uniform(0.03, 0.15), b = rng.uniform(0.08, 0.45), p = rng.uniform(0.7, 2.2);
    const double shoulder = rng.chance(0.5) ? rng.uniform(0.02, 0.12) : 0.0;
    const double sh_mu = rng.uniform(530, 620), sh_w = rng.uniform(15, 35);
    for (std::size_t i = 0; i < n; ++i) {
      const double l = nm[i];
      const double t = std::clamp((l - 380) / 400, 0.0, 1.5);
      const double v = a + b * std::pow(t, p) + shoulder * logistic((l - sh_mu) / sh_w);
      r[i] = std::clamp(v, 0.02, 0.95);
    }
    return r;
  }
  // near-neutral: stone, concrete, ash
  const double level = rng.uniform(0.08, 0.6), tilt = rng.uniform(-0.08, 0.12);
  for (std::size_t i = 0; i < n; ++i) r[i] = std::clamp(level * (1 + tilt * (nm[i] - 580) / 200), 0.02, 0.95);
  return r;
}

/// A rotated ellipse: centre, semi-axes, rotation; q(x, y) = 1 on the boundary.
struct Ellipse {
  double cx, cy, a, b, cos_t, sin_t;
  double half_w, half_h;  // half extents of the axis-aligned bounding box
  Ellipse(double cx_, double cy_, double a_, double b_, double theta)
      : cx(cx_), cy(cy_), a(a_), b(b_), cos_t(std::cos(theta)), sin_t(std::sin(theta)) {
    half_w = std::sqrt(a * a * cos_t * cos_t + b * b * sin_t * sin_t);
    half_h = std::sqrt(a * a * sin_t * sin_t + b * b * cos_t * cos_t);
  }
  /// Pixel range [x0, x1) of row y inside the bounding box (empty when x0 >= x1).
  void row_range(double y, std::size_t width, std::size_t& x0, std::size_t& x1) const {
    x0 = x1 = 0;
    if (std::abs(y - cy) > half_h) return;
    const double lo = std::max(0.0, std::floor(cx - half_w)), hi = std::min(double(width), std::ceil(cx + half_w) + 1);
    if (lo >= hi) return;
    x0 = static_cast<std::size_t>(lo);
    x1 = static_cast<std::size_t>(hi);
  }
  float q(double x, double y) const {
    const double dx = x - cx, dy = y - cy;
    const double u = (dx * cos_t + dy * sin_t) / a, v = (-dx * sin_t + dy * cos_t) / b;
    return static_cast<float>(u * u + v * v);
  }
};

/// A plane wave cos(kx x + ky y + phase) stored as column tables, so a row needs only two per-row values.
struct Wave {
  double kx, ky, phase, amp;
  std::vector<float> cx, sx;  // cos / sin of (kx x + phase) for every column
  void tabulate(std::size_t width) {
    cx.resize(width);
    sx.resize(width);
    for (std::size_t x = 0; x < width; ++x) {
      const double t = kx * double(x) + phase;
      cx[x] = static_cast<float>(std::cos(t));
      sx[x] = static_cast<float>(std::sin(t));
    }
  }
  /// out[x] += amp * cos(kx x + ky y + phase) for the whole row.
  void add_row(double y, float* out, std::size_t width) const {
    const float c = static_cast<float>(amp * std::cos(ky * y)), s = static_cast<float>(amp * std::sin(ky * y));
    for (std::size_t x = 0; x < width; ++x) out[x] += c * cx[x] - s * sx[x];
  }
};

struct Region {
  std::uint32_t material;  // palette index
  float orientation;       // cos(incidence) of the surface
  std::uint32_t pattern;   // texture pattern index
  float texture_amp;
};

struct StraightShadow {
  double nx, ny, c, width;  // shadow where nx x + ny y > c, ramp over `width` pixels
};

constexpr std::size_t kBlock = 8;
constexpr std::size_t kPatterns = 4;

/// Everything about one image except the per-pixel random numbers.
struct Scene {
  std::size_t height = 0, width = 0, bands = 0, stride = 0;  // stride: bands padded to 16
  // Spectra: per material, reflectance x sun and reflectance x sky (already scaled), stride floats each.
  std::vector<float> sunlit, skylit;
  std::vector<double> mean_sun, mean_sky;  // band means of the above, per material
  std::vector<Region> regions;             // power-diagram cells first, then objects
  std::vector<float> seed_x, seed_y, seed_w;
  std::vector<Ellipse> objects;
  std::vector<std::uint32_t> object_region;
  std::vector<std::uint32_t> corner_label;  // labels at block corners, ncx x ncy
  std::size_t ncx = 0, ncy = 0;
  std::vector<Wave> shading;   // slowly varying shading field
  std::vector<Wave> patterns;  // texture patterns
  std::vector<Ellipse> shadows;
  std::vector<float> shadow_softness;  // in units of q
  std::vector<StraightShadow> straight_shadows;
  struct Rect {
    std::size_t y0, y1, x0, x1;
  };
  std::vector<Rect> masked;
  float grain = 0;

  std::uint32_t cell_at(float x, float y) const {
    std::uint32_t best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < seed_x.size(); ++i) {
      const float dx = x - seed_x[i], dy = y - seed_y[i];
      const float d = dx * dx + dy * dy - seed_w[i];
      if (d < best_d) {
        best_d = d;
        best = static_cast<std::uint32_t>(i);
      }
    }
    return best;
  }

  /// Fills the per-row scene quantities: region label, scalar gain (orientation x shading x texture,
  /// without grain) and shadow fraction (0 lit, 1 sky only).
  void row(std::size_t y, std::uint32_t* label, float* gain, float* shadow, float* scratch) const {
    const double fy = double(y);
    // labels: block trick on the power diagram, then objects painted on top
    const std::size_t by = y / kBlock;
    const std::uint32_t* c0 = corner_label.data() + by * ncx;
    const std::uint32_t* c1 = c0 + ncx;
    for (std::size_t bx = 0; bx * kBlock < width; ++bx) {
      const std::size_t x_end = std::min(width, (bx + 1) * kBlock);
      const std::uint32_t l = c0[bx];
      if (l == c0[bx + 1] && l == c1[bx] && l == c1[bx + 1]) {
        for (std::size_t x = bx * kBlock; x < x_end; ++x) label[x] = l;
      } else {
        for (std::size_t x = bx * kBlock; x < x_end; ++x) label[x] = cell_at(float(x), float(y));
      }
    }
    for (std::size_t k = 0; k < objects.size(); ++k) {
      std::size_t x0, x1;
      objects[k].row_range(fy, width, x0, x1);
      for (std::size_t x = x0; x < x1; ++x)
        if (objects[k].q(double(x), fy) < 1.0f) label[x] = object_region[k];
    }
    // shading field
    std::fill(scratch, scratch + width, 1.0f);
    for (const auto& w : shading) w.add_row(fy, scratch, width);
    // texture patterns: kPatterns rows after scratch
    float* tex = scratch + width;
    std::fill(tex, tex + kPatterns * width, 0.0f);
    for (std::size_t p = 0; p < patterns.size(); ++p) patterns[p].add_row(fy, tex + p * width, width);
    for (std::size_t x = 0; x < width; ++x) {
      const Region& r = regions[label[x]];
      gain[x] = r.orientation * scratch[x] * (1.0f + r.texture_amp * tex[r.pattern * width + x]);
    }
    // shadows
    std::fill(shadow, shadow + width, 0.0f);
    for (std::size_t k = 0; k < shadows.size(); ++k) {
      std::size_t x0, x1;
      shadows[k].row_range(fy, width, x0, x1);
      const float inv_soft = 1.0f / shadow_softness[k];
      for (std::size_t x = x0; x < x1; ++x) {
        const float s = std::clamp((1.0f - shadows[k].q(double(x), fy)) * inv_soft, 0.0f, 1.0f);
        shadow[x] = std::max(shadow[x], s);
      }
    }
    for (const auto& s : straight_shadows) {
      const float a = float(s.nx / s.width), b = float((s.ny * fy - s.c) / s.width);
      for (std::size_t x = 0; x < width; ++x) shadow[x] = std::max(shadow[x], std::clamp(a * float(x) + b, 0.0f, 1.0f));
    }
  }
};

// The scene's light (sun and sky daylights) and its palette of materials lit by both; returns the material count.
int add_palette(Scene& sc, Rng& rng, const SynthOptions& o) {
  const auto nm = o.wavelengths.values();
  // illumination
  const double cct_sun = rng.uniform(4000, 12000);
  const double cct_sky = std::min(25000.0, std::max(rng.uniform(10000, 20000), cct_sun + 1000));
  const double intensity = rng.log_uniform(0.3, 3.0);
  const double sky_fraction = rng.uniform(0.10, 0.30);
  const Eigen::VectorXd sun = daylight(cct_sun, o.wavelengths) * (intensity / 100.0);
  const Eigen::VectorXd sky = daylight(cct_sky, o.wavelengths) * (intensity * sky_fraction / 100.0);

  // palette
  const int materials = rng.integer(20, 60);
  sc.sunlit.assign(std::size_t(materials) * sc.stride, 0.0f);
  sc.skylit.assign(std::size_t(materials) * sc.stride, 0.0f);
  sc.mean_sun.assign(std::size_t(materials), 0.0);
  sc.mean_sky.assign(std::size_t(materials), 0.0);
  for (int m = 0; m < materials; ++m) {
    const auto refl = make_reflectance(rng, nm);
    float* a = sc.sunlit.data() + std::size_t(m) * sc.stride;
    float* b = sc.skylit.data() + std::size_t(m) * sc.stride;
    for (std::size_t i = 0; i < sc.bands; ++i) {
      a[i] = static_cast<float>(refl[i] * sun[Eigen::Index(i)]);
      b[i] = static_cast<float>(refl[i] * sky[Eigen::Index(i)]);
      sc.mean_sun[std::size_t(m)] += a[i];
      sc.mean_sky[std::size_t(m)] += b[i];
    }
    sc.mean_sun[std::size_t(m)] /= double(sc.bands);
    sc.mean_sky[std::size_t(m)] /= double(sc.bands);
  }

  return materials;
}

// The regions of the power diagram and the objects over it, each with a material, orientation and texture.
void add_layout(Scene& sc, Rng& rng, double H, double W, int materials) {
  auto new_region = [&] {
    Region r;
    r.material = static_cast<std::uint32_t>(rng.integer(0, materials - 1));
    r.orientation = static_cast<float>(rng.uniform(0.35, 1.0));
    r.pattern = static_cast<std::uint32_t>(rng.integer(0, int(kPatterns) - 1));
    r.texture_amp = static_cast<float>(rng.uniform(0.01, 0.08));
    return r;
  };

  // layout: power diagram
  const int cells = rng.integer(12, 40);
  const double cell_area = H * W / cells;
  for (int i = 0; i < cells; ++i) {
    sc.seed_x.push_back(static_cast<float>(rng.uniform(-0.05, 1.05) * W));
    sc.seed_y.push_back(static_cast<float>(rng.uniform(-0.05, 1.05) * H));
    sc.seed_w.push_back(static_cast<float>(rng.uniform(0, 0.6) * cell_area));
    sc.regions.push_back(new_region());
  }
  const int n_objects = rng.integer(0, 6);
  const double small = std::min(H, W);
  for (int i = 0; i < n_objects; ++i) {
    sc.objects.emplace_back(rng.uniform(0, W), rng.uniform(0, H), rng.uniform(0.03, 0.15) * small + 1,
                            rng.uniform(0.03, 0.15) * small + 1, rng.uniform(0, kPi));
    sc.object_region.push_back(static_cast<std::uint32_t>(sc.regions.size()));
    sc.regions.push_back(new_region());
  }
}

// Shading waves and cast shadows (soft ellipses, sometimes one straight edge).
void add_shading_and_shadows(Scene& sc, Rng& rng, double H, double W) {
  // shading: three slowly varying plane waves, total amplitude <= 0.36
  const double big = std::max(H, W);
  for (int i = 0; i < 3; ++i) {
    const double period = rng.uniform(0.6, 2.5) * big, theta = rng.uniform(0, 2 * kPi);
    const double k = 2 * kPi / period;
    sc.shading.push_back(
        {k * std::cos(theta), k * std::sin(theta), rng.uniform(0, 2 * kPi), rng.uniform(0.03, 0.12), {}, {}});
  }

  // cast shadows
  const int n_shadows = rng.integer(0, 3);
  for (int i = 0; i < n_shadows; ++i) {
    sc.shadows.emplace_back(rng.uniform(0, W), rng.uniform(0, H), rng.uniform(0.08, 0.35) * W + 1,
                            rng.uniform(0.08, 0.35) * H + 1, rng.uniform(0, kPi));
    sc.shadow_softness.push_back(static_cast<float>(rng.uniform(0.03, 0.25)));
  }
  if (rng.chance(0.35)) {
    const double theta = rng.uniform(0, 2 * kPi);
    const double nx = std::cos(theta), ny = std::sin(theta);
    const double corners[4] = {0, nx * W, ny * H, nx * W + ny * H};
    const double pmin = *std::min_element(corners, corners + 4), pmax = *std::max_element(corners, corners + 4);
    const double cover = rng.uniform(0.1, 0.35);
    sc.straight_shadows.push_back({nx, ny, pmax - cover * (pmax - pmin), rng.uniform(1.5, 8)});
  }
}

// 0-3 masked rectangles.
void add_mask(Scene& sc, Rng& rng, const SynthOptions& o) {
  const double H = double(o.height), W = double(o.width);
  // mask: 0-3 rectangles
  const int n_masked = rng.integer(0, 3);
  for (int i = 0; i < n_masked; ++i) {
    const double h = rng.uniform(0.08, 0.3) * H, w = rng.uniform(0.05, 0.2) * W;
    const double y0 = rng.uniform(0, H - h), x0 = rng.uniform(0, W - w);
    Scene::Rect r;
    r.y0 = static_cast<std::size_t>(y0);
    r.x0 = static_cast<std::size_t>(x0);
    r.y1 = std::min(o.height, std::max(r.y0 + 1, static_cast<std::size_t>(y0 + h)));
    r.x1 = std::min(o.width, std::max(r.x0 + 1, static_cast<std::size_t>(x0 + w)));
    sc.masked.push_back(r);
  }
}

Scene make_scene(const SynthOptions& o, std::uint64_t image_seed) {
  Rng rng(image_seed);
  Scene sc;
  sc.height = o.height;
  sc.width = o.width;
  sc.bands = o.wavelengths.size();
  sc.stride = (sc.bands + 15) / 16 * 16;
  const double H = double(o.height), W = double(o.width);
  const int materials = add_palette(sc, rng, o);
  // texture patterns and per-image grain
  for (std::size_t p = 0; p < kPatterns; ++p) {
    const double period = rng.log_uniform(3, 30), theta = rng.uniform(0, kPi);
    const double k = 2 * kPi / period;
    sc.patterns.push_back({k * std::cos(theta), k * std::sin(theta), rng.uniform(0, 2 * kPi), 1.0, {}, {}});
  }
  sc.grain = static_cast<float>(rng.uniform(0.005, 0.02));

  add_layout(sc, rng, H, W, materials);
  add_shading_and_shadows(sc, rng, H, W);
  add_mask(sc, rng, o);
  for (auto& w : sc.shading) w.tabulate(o.width);
  for (auto& w : sc.patterns) w.tabulate(o.width);

  // power-diagram labels at block corners (convex cells: equal corners => the whole block)
  sc.ncx = (o.width - 1) / kBlock + 2;
  sc.ncy = (o.height - 1) / kBlock + 2;
  sc.corner_label.resize(sc.ncx * sc.ncy);
  for (std::size_t j = 0; j < sc.ncy; ++j)
    for (std::size_t i = 0; i < sc.ncx; ++i)
      sc.corner_label[j * sc.ncx + i] =
          sc.cell_at(float(std::min(i * kBlock, o.width - 1)), float(std::min(j * kBlock, o.height - 1)));
  return sc;
}

/// Reserves n floats in v and, on Linux, has the kernel map the pages from all threads at once
/// (MADV_POPULATE_WRITE): first-touch page faults of a fresh 180 MB cube otherwise cost more than
/// synthesising it, all on one thread. A hint only; on older kernels it does nothing.
void prefault(std::vector<float>& v, std::size_t n) {
  v.reserve(n);
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
  constexpr std::size_t kMin = std::size_t{16} << 20;  // not worth a thread team below 16 MB
  const std::size_t bytes = n * sizeof(float);
  if (bytes < kMin) return;
  const long page_size = ::sysconf(_SC_PAGESIZE);
  if (page_size <= 0) return;
  const auto page = static_cast<std::uintptr_t>(page_size);
  const auto begin = (reinterpret_cast<std::uintptr_t>(v.data()) + page - 1) / page * page;
  const auto end = (reinterpret_cast<std::uintptr_t>(v.data()) + bytes) / page * page;
  if (end <= begin) return;
  const std::size_t pages = (end - begin) / page;
  constexpr std::size_t kPiece = 1024;  // pages per madvise call (4 MB of 4 KB pages)
  const std::size_t pieces = (pages + kPiece - 1) / kPiece;
  parallel_for(pieces, [&](std::size_t i) {
    const std::size_t first = i * kPiece, count = std::min(kPiece, pages - first);
    ::madvise(reinterpret_cast<void*>(begin + first * page), count * page, MADV_POPULATE_WRITE);
  });
#endif
}

void check_options(const SynthOptions& options, std::size_t index) {
  if (options.height == 0 || options.width == 0)
    throw UsageError("synthetic image size must be at least 1x1, got " + std::to_string(options.height) + "x" +
                     std::to_string(options.width));
  if (options.wavelengths.empty()) throw UsageError("synthetic images need a non-empty wavelength grid");
  if (index >= options.images)
    throw UsageError("synthetic image index " + std::to_string(index) + " is out of range: the database has " +
                     std::to_string(options.images) + " image(s)");
  if (!std::isfinite(options.noise) || options.noise < 0)
    throw UsageError("synthetic noise must be a finite number >= 0, got " + std::to_string(options.noise));
  {
    const CieTable basis = daylight_basis_table();  // daylight() is zero outside its table: refuse instead
    if (options.wavelengths.front() < basis.nm.front() || options.wavelengths.back() > basis.nm.back())
      throw UsageError("synthetic images need wavelengths within the CIE daylight table, " +
                       std::to_string(int(basis.nm.front())) + "-" + std::to_string(int(basis.nm.back())) +
                       " nm; got " + options.wavelengths.describe());
  }
  const std::size_t H = options.height, W = options.width, B = options.wavelengths.size();
  if (W > (std::size_t{1} << 24) || H > (std::size_t{1} << 24) ||
      H * W > std::numeric_limits<std::size_t>::max() / 4 / B)
    throw UsageError("synthetic image " + std::to_string(H) + "x" + std::to_string(W) + "x" + std::to_string(B) +
                     " is too large");
}

// Mean noise-free radiance of the scene from up to 64 sampled rows, for the noise scale.
double mean_radiance(const Scene& sc, std::size_t H, std::size_t W) {
  const std::size_t rows = std::min<std::size_t>(H, 64);
  std::vector<std::uint32_t> label(W);
  std::vector<float> gain(W), shadow(W), scratch((1 + kPatterns) * W);
  double sum = 0;
  for (std::size_t i = 0; i < rows; ++i) {
    const std::size_t y = (2 * i + 1) * H / (2 * rows);
    sc.row(y, label.data(), gain.data(), shadow.data(), scratch.data());
    for (std::size_t x = 0; x < W; ++x) {
      const std::uint32_t m = sc.regions[label[x]].material;
      sum += gain[x] * ((1.0 - shadow[x]) * sc.mean_sun[m] + sc.mean_sky[m]);
    }
  }
  return sum / double(rows * W);
}

}  // namespace

Cube synthesize_image(const SynthOptions& options, std::size_t index) {
  check_options(options, index);
  const std::size_t H = options.height, W = options.width, B = options.wavelengths.size();
  std::uint64_t s = options.seed;
  const std::uint64_t image_seed = mix(splitmix64(s), index + 1);
  const Scene sc = make_scene(options, image_seed);

  Cube cube;
  prefault(cube.data, H * W * B);
  cube.resize(H, W, B);
  cube.wavelengths = options.wavelengths;
  cube.units = "radiance";
  cube.provenance.importer = "synth-db";
  cube.mask.assign(H * W, 1);
  for (const auto& r : sc.masked)
    for (std::size_t y = r.y0; y < r.y1; ++y)
      std::fill_n(cube.mask.begin() + std::ptrdiff_t(y * W + r.x0), r.x1 - r.x0, 0);

  const double mean = options.noise > 0 ? mean_radiance(sc, H, W) : 0.0;
  const float var_read = static_cast<float>(options.noise * options.noise * mean * mean);
  const float var_shot = static_cast<float>(4 * options.noise * options.noise * mean);
  const bool noisy = options.noise > 0 && mean > 0;
  const std::size_t stride = sc.stride;
  const std::size_t block = (B + 1 + 15) / 16 * 16;  // deviates per pixel: B for the sensor, one for grain
  // pixels of a row whose padded write (stride floats) stays inside the row
  const std::size_t direct = W * B >= stride ? std::min(W, (W * B - stride) / B + 1) : 0;

  // Spectra are processed in fixed packets of 16 floats (stride is a multiple of 16), no peeling.
  using Packet = Eigen::Array<float, 16, 1>;
  using PacketMap = Eigen::Map<Packet>;
  using ConstPacketMap = Eigen::Map<const Packet>;
  struct RowScratch {
    std::vector<std::uint32_t> label;
    std::vector<float> gain, shadow, scratch, last;
  };
  parallel_for(
      H,
      [&] {
        return RowScratch{std::vector<std::uint32_t>(W), std::vector<float>(W), std::vector<float>(W),
                          std::vector<float>((1 + kPatterns) * W), std::vector<float>(stride)};
      },
      [&](std::size_t y, RowScratch& t) {
        // One pixel: radiance into dst[0..stride); dst[B..stride) is scratch that the following pixels
        // overwrite. Pixels near the row's end go through `last` so no write passes the row's end.
        auto pixel = [&](float* dst, std::size_t x, const float* n) {
          const float g = t.gain[x] * (1.0f + sc.grain * n[B]);
          const float ga = g * (1.0f - t.shadow[x]);
          const std::size_t m = sc.regions[t.label[x]].material;
          const float* a = sc.sunlit.data() + m * stride;
          const float* b = sc.skylit.data() + m * stride;
          for (std::size_t c = 0; c < stride; c += 16) {
            Packet v = ga * ConstPacketMap(a + c) + g * ConstPacketMap(b + c);
            if (noisy) v += (var_read + var_shot * v.max(0.0f)).sqrt() * ConstPacketMap(n + c);
            PacketMap(dst + c) = v;
          }
        };
        NormalStream normals(mix(image_seed, 0x5EED0000ull + y), block);
        sc.row(y, t.label.data(), t.gain.data(), t.shadow.data(), t.scratch.data());
        float* out = cube.data.data() + y * W * B;
        std::size_t x = 0;
        for (; x < direct; ++x, out += B) pixel(out, x, normals.take());
        for (; x < W; ++x, out += B) {
          pixel(t.last.data(), x, normals.take());
          std::memcpy(out, t.last.data(), B * sizeof(float));
        }
      },
      16);
  return cube;
}

}  // namespace specula::store
