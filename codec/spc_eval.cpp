#include "specula/codec/spc_eval.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

using brdf::kMerlCells;

// atan2(y, x) for y >= 0 or any y, in float, branch-free so that loops over it vectorise: the ratio of the
// smaller to the larger magnitude reduced to |t| <= tan(pi/8) and Cephes' atanf polynomial (about 1e-7 absolute).
inline float atan2_float(float y, float x) {
  const float ax = std::abs(x), ay = std::abs(y);
  const float hi = std::max(ax, ay), lo = std::min(ax, ay);
  const float a = lo / std::max(hi, 1e-30f);
  const bool reduce = a > 0.41421356f;
  const float reduced = (a - 1.0f) / (a + 1.0f);
  const float t = reduce ? reduced : a;
  const float z = t * t;
  float r = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z - 3.33329491539e-1f) * z * t + t;
  r += reduce ? 0.78539816f : 0.0f;
  r = ay > ax ? 1.57079633f - r : r;
  r = x < 0 ? 3.14159265f - r : r;
  return y < 0 ? -r : r;
}

// A pair is redone in double when an index coordinate lies within kBoundaryMargin of an integer (on 4 million
// random pairs the float path's coordinates were at most 4e-4 from the double ones), or when a quantity the float
// path divides by is small: |wi + wo| (kMinHalfLength), the half vector's distance from the normal (its phi is
// ill-conditioned) and the difference vector's (phi_d ill-conditioned), both kMinSine.
constexpr float kBoundaryMargin = 2e-3f;
constexpr float kMinHalfLength = 0.25f;
constexpr float kMinSine = 0.1f;

// The float path over one block; flags[i] = 1 where the pair must be redone in double.
void float_indices(const float* wi, const float* wo, std::size_t n, std::uint32_t* cells, std::uint8_t* flags) {
  constexpr float kInvHalfPi = float(2 / std::numbers::pi), kDegPerRad = float(180 / std::numbers::pi);
  constexpr float kPi = float(std::numbers::pi);
  for (std::size_t i = 0; i < n; ++i) {
    float ix = wi[3 * i], iy = wi[3 * i + 1], iz = wi[3 * i + 2];
    float ox = wo[3 * i], oy = wo[3 * i + 1], oz = wo[3 * i + 2];
    const float li = 1.0f / std::sqrt(ix * ix + iy * iy + iz * iz), lo = 1.0f / std::sqrt(ox * ox + oy * oy + oz * oz);
    ix *= li, iy *= li, iz *= li, ox *= lo, oy *= lo, oz *= lo;
    float hx = ix + ox, hy = iy + oy, hz = iz + oz;
    const float hl = std::sqrt(hx * hx + hy * hy + hz * hz), hinv = 1.0f / hl;
    hx *= hinv, hy *= hinv, hz *= hinv;
    const float hxy = std::sqrt(hx * hx + hy * hy), hxy_inv = 1.0f / hxy;
    const float c = hx * hxy_inv, s = hy * hxy_inv;
    // wi turned by -phi_h about the normal, then by -theta_h about the binormal (cos theta_h = hz, sin = hxy).
    const float ux = c * ix + s * iy, uy = c * iy - s * ix;
    const float dx = hz * ux - hxy * iz, dy = uy, dz = hxy * ux + hz * iz;
    const float dxy = std::sqrt(dx * dx + dy * dy);
    const float theta_h = atan2_float(hxy, hz), theta_d = atan2_float(dxy, dz);
    float phi_d = atan2_float(dy, dx);
    phi_d = phi_d < 0 ? phi_d + kPi : phi_d;
    float xh = 90.0f * std::sqrt(theta_h * kInvHalfPi), xd = theta_d * kDegPerRad, xp = phi_d * kDegPerRad;
    // Non-short-circuit & keeps the loop free of branches, so that it vectorises.
    bool ok = (hl > kMinHalfLength) & (hxy > kMinSine) & (dxy > kMinSine) & (xh >= 0) & (xh < 256) & (xd >= 0) &
              (xd < 256) & (xp >= 0) & (xp < 256);
    xh = ok ? xh : 0.0f, xd = ok ? xd : 0.0f, xp = ok ? xp : 0.0f;
    const int th = int(xh), td = int(xd), tp = int(xp);
    const float fh = xh - float(th), fd = xd - float(td), fp = xp - float(tp);
    ok = ok & (fh > kBoundaryMargin) & (fh < 1 - kBoundaryMargin) & (fd > kBoundaryMargin) &
         (fd < 1 - kBoundaryMargin) & (fp > kBoundaryMargin) & (fp < 1 - kBoundaryMargin);
    const int ch = std::min(th, brdf::kMerlThetaH - 1), cd = std::min(td, brdf::kMerlThetaD - 1),
              cp = std::min(tp, brdf::kMerlPhiD - 1);
    cells[i] = std::uint32_t(cp + brdf::kMerlPhiD * (cd + brdf::kMerlThetaD * ch));
    flags[i] = ok ? 0 : 1;
  }
}

std::uint32_t reference_index(const float* wi, const float* wo) {
  const Eigen::Vector3d i(wi[0], wi[1], wi[2]), o(wo[0], wo[1], wo[2]);
  return std::uint32_t(brdf::merl_index(brdf::merl_cell(brdf::half_diff(i, o))));
}

constexpr std::size_t kBlock = 256;

void check_pairs(std::size_t wi, std::size_t wo, const char* what) {
  if (wi % 3 != 0 || wi != wo)
    throw UsageError(std::string(what) + ": wi holds " + std::to_string(wi) + " floats and wo " + std::to_string(wo) +
                     "; give both as n x 3 floats (x, y, z per direction)");
}

}  // namespace

void merl_indices(std::span<const float> wi, std::span<const float> wo, std::span<std::uint32_t> cells) {
  check_pairs(wi.size(), wo.size(), "merl_indices");
  const std::size_t n = wi.size() / 3;
  if (cells.size() != n)
    throw UsageError("merl_indices: " + std::to_string(cells.size()) + " cell slots for " + std::to_string(n) +
                     " direction pairs; give one per pair");
  std::uint8_t flags[kBlock];
  for (std::size_t first = 0; first < n; first += kBlock) {
    const std::size_t m = std::min(kBlock, n - first);
    float_indices(wi.data() + 3 * first, wo.data() + 3 * first, m, cells.data() + first, flags);
    for (std::size_t i = 0; i < m; ++i)
      if (flags[i]) cells[first + i] = reference_index(wi.data() + 3 * (first + i), wo.data() + 3 * (first + i));
  }
}

SpcBrdf::SpcBrdf(SpcCoefficients&& c)
    : wavelengths_(std::move(c.wavelengths)), source_(std::move(c.source)), reference_(std::move(c.reference)) {
  k_ = c.k();
  bands_ = c.bands();
  if (k_ == 0 || bands_ == 0 || bands_ != wavelengths_.size())
    throw UsageError("SpcBrdf: a basis of " + std::to_string(k_) + " x " + std::to_string(bands_) + " on " +
                     std::to_string(wavelengths_.size()) +
                     " wavelengths; give k >= 1 rows of one value per wavelength");
  if (c.values.size() != k_ * kMerlCells || c.valid.size() != kMerlCells)
    throw UsageError("SpcBrdf: " + std::to_string(c.values.size()) + " coefficients and " +
                     std::to_string(c.valid.size()) + " validity flags; expected k x 90 x 90 x 180 = " +
                     std::to_string(k_ * kMerlCells) + " and " + std::to_string(kMerlCells));
  if (!(c.scale > 0) || !std::isfinite(c.scale))
    throw UsageError("SpcBrdf: scale " + std::to_string(c.scale) + "; give a positive finite scale");
  padded_ = (bands_ + 7) / 8 * 8;
  basis_.assign(k_ * padded_, 0.0f);
  for (std::size_t j = 0; j < k_; ++j)
    for (std::size_t b = 0; b < bands_; ++b)
      basis_[j * padded_ + b] = float(c.basis(Eigen::Index(j), Eigen::Index(b)) * c.scale);
  // The cells are read in random order: on 2 MB pages (a Buffer's, core/buffer.h) their table costs a few TLB
  // entries instead of thousands.
  values_ = std::move(c.values);
  valid_ = std::move(c.valid);
}

std::size_t SpcBrdf::memory_bytes() const {
  return values_.capacity() * sizeof(float) + valid_.capacity() + basis_.capacity() * sizeof(float);
}

namespace {

// out[b] = max(0, sum_j a_j v[j * P + b]) for b < bands <= P, summed in registers over the padded width P.
template <std::size_t P>
inline void expand_padded(const float* a, std::size_t k, const float* v, float* out, std::size_t bands) {
  float acc[P];
  for (std::size_t b = 0; b < P; ++b) acc[b] = a[0] * v[b];
  for (std::size_t j = 1; j < k; ++j)
    for (std::size_t b = 0; b < P; ++b) acc[b] += a[j] * v[j * P + b];
  for (std::size_t b = 0; b < bands; ++b) out[b] = std::max(0.0f, acc[b]);
}

// expand_padded of C cells at once (a: their coefficients; out: C x bands): their sums are independent chains the
// core runs side by side; each is summed as expand_padded sums it.
template <std::size_t P, std::size_t C>
inline void expand_cells(const float* const* a, std::size_t k, const float* v, float* out, std::size_t bands) {
  float acc[C][P];
  for (std::size_t c = 0; c < C; ++c)
    for (std::size_t b = 0; b < P; ++b) acc[c][b] = a[c][0] * v[b];
  for (std::size_t j = 1; j < k; ++j)
    for (std::size_t c = 0; c < C; ++c)
      for (std::size_t b = 0; b < P; ++b) acc[c][b] += a[c][j] * v[j * P + b];
  for (std::size_t c = 0; c < C; ++c)
    for (std::size_t b = 0; b < bands; ++b) out[c * bands + b] = std::max(0.0f, acc[c][b]);
}

// expand_cells of cells[0, C) of the table (k floats a cell) on a basis padded to 16 or 32 floats a coefficient.
template <std::size_t C>
inline void expand_together(const float* table, std::size_t k, const float* basis, std::size_t padded,
                            const std::uint32_t* cells, float* out, std::size_t bands) {
  const float* a[C];
  for (std::size_t c = 0; c < C; ++c) a[c] = table + std::size_t(cells[c]) * k;
  if (padded == 16) return expand_cells<16, C>(a, k, basis, out, bands);
  expand_cells<32, C>(a, k, basis, out, bands);
}

}  // namespace

void SpcBrdf::expand(std::size_t cell, float* out) const {
  const float* a = values_.data() + cell * k_;
  const float* v = basis_.data();
  switch (padded_) {
    case 8:
      return expand_padded<8>(a, k_, v, out, bands_);
    case 16:
      return expand_padded<16>(a, k_, v, out, bands_);
    case 32:
      return expand_padded<32>(a, k_, v, out, bands_);
    default:
      break;
  }
  for (std::size_t b = 0; b < bands_; ++b) out[b] = a[0] * v[b];
  for (std::size_t j = 1; j < k_; ++j)
    for (std::size_t b = 0; b < bands_; ++b) out[b] += a[j] * v[j * padded_ + b];
  for (std::size_t b = 0; b < bands_; ++b) out[b] = std::max(0.0f, out[b]);
}

void SpcBrdf::evaluate_cell(std::size_t cell, std::span<float> out) const {
  if (out.size() != bands_ || cell >= kMerlCells)
    throw UsageError("SpcBrdf::evaluate_cell: cell " + std::to_string(cell) + " into " + std::to_string(out.size()) +
                     " values; give a cell below " + std::to_string(kMerlCells) + " and " + std::to_string(bands_) +
                     " values");
  expand(cell, out.data());
}

bool SpcBrdf::evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<float> out) const {
  if (out.size() != bands_)
    throw UsageError("SpcBrdf::evaluate: " + std::to_string(out.size()) + " output values; give " +
                     std::to_string(bands_) + ", one per band");
  const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::half_diff(wi, wo)));
  expand(cell, out.data());
  return valid_[cell] != 0;
}

void SpcBrdf::evaluate(std::span<const float> wi, std::span<const float> wo, std::span<float> out) const {
  check_pairs(wi.size(), wo.size(), "SpcBrdf::evaluate");
  const std::size_t n = wi.size() / 3;
  if (out.size() != n * bands_)
    throw UsageError("SpcBrdf::evaluate: " + std::to_string(out.size()) + " output values for " + std::to_string(n) +
                     " direction pairs; give n x " + std::to_string(bands_));
  // Chunks of kChunkBlocks blocks; within a chunk the next block's cells are found first and each of them is
  // prefetched while the current block's pairs are expanded, so the table's misses overlap the arithmetic.
  constexpr std::size_t kChunkBlocks = 16, kChunk = kChunkBlocks * kBlock;
  // Four pairs (then two) expanded together where the padded width has a kernel.
  const bool together = padded_ == 16 || padded_ == 32;
  // A cell's first and last coefficient: more than 16 floats a cell span two cache lines.
  const auto prefetch = [&](std::uint32_t cell) {
    __builtin_prefetch(values_.data() + std::size_t(cell) * k_);
    __builtin_prefetch(values_.data() + std::size_t(cell) * k_ + k_ - 1);
  };
  parallel_for((n + kChunk - 1) / kChunk, [] { return std::vector<std::uint32_t>(2 * kBlock); },
               [&](std::size_t chunk, std::vector<std::uint32_t>& cells) {
                 const std::size_t begin = chunk * kChunk, end = std::min(n, begin + kChunk);
                 auto find = [&](std::size_t first, std::uint32_t* into) {
                   const std::size_t m = std::min(kBlock, end - first);
                   merl_indices(wi.subspan(3 * first, 3 * m), wo.subspan(3 * first, 3 * m), std::span(into, m));
                 };
                 std::uint32_t* now = cells.data();
                 std::uint32_t* next = cells.data() + kBlock;
                 find(begin, now);
                 for (std::size_t i = 0; i < std::min(kBlock, end - begin); ++i) prefetch(now[i]);
                 for (std::size_t first = begin; first < end; first += kBlock) {
                   const std::size_t m = std::min(kBlock, end - first);
                   const bool more = first + kBlock < end;
                   const std::size_t m_next = more ? std::min(kBlock, end - first - kBlock) : 0;
                   if (more) find(first + kBlock, next);
                   std::size_t i = 0;
                   for (; together && i + 3 < m; i += 4) {
                     for (std::size_t q = i; q < i + 4; ++q)
                       if (q < m_next) prefetch(next[q]);
                     expand_together<4>(values_.data(), k_, basis_.data(), padded_, now + i,
                                        out.data() + (first + i) * bands_, bands_);
                   }
                   for (; together && i + 1 < m; i += 2) {
                     if (i < m_next) prefetch(next[i]);
                     if (i + 1 < m_next) prefetch(next[i + 1]);
                     expand_together<2>(values_.data(), k_, basis_.data(), padded_, now + i,
                                        out.data() + (first + i) * bands_, bands_);
                   }
                   for (; i < m; ++i) {
                     if (i < m_next) prefetch(next[i]);
                     expand(now[i], out.data() + (first + i) * bands_);
                   }
                   std::swap(now, next);
                 }
               });
}

}  // namespace specula::codec
