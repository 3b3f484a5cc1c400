#include "specula/codec/wavelet.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "specula/core/error.h"

namespace specula::codec::wavelet {
namespace {

// CDF 9/7 lifting steps and scaling (Daubechies & Sweldens 1998).
constexpr float kAlpha = -1.586134342059924f, kBeta = -0.052980118572961f, kGamma = 0.882911075530934f,
                kDelta = 0.443506852043971f, kScale = 1.149604398860241f;

// One lifting step on the rows of parity `parity` (0: even, 1: odd) of n rows of `width` values each, rows
// `stride` apart: row i += c (row i-1 + row i+1), mirrored at both ends (row -1 = row 1, row n = row n-2).
void lift(float* x, std::size_t n, std::size_t stride, std::size_t width, std::size_t parity, float c) {
  for (std::size_t i = parity; i < n; i += 2) {
    const std::size_t l = i > 0 ? i - 1 : i + 1, r = i + 1 < n ? i + 1 : i - 1;
    float* row = x + i * stride;
    const float* a = x + l * stride;
    const float* b = x + r * stride;
    for (std::size_t k = 0; k < width; ++k) row[k] += c * (a[k] + b[k]);
  }
}

void scale(float* x, std::size_t n, std::size_t stride, std::size_t width, bool inverse) {
  for (std::size_t i = 0; i < n; ++i) {
    const float s = (i % 2 == 0) == inverse ? kScale : 1 / kScale;
    float* row = x + i * stride;
    for (std::size_t k = 0; k < width; ++k) row[k] *= s;
  }
}

// The 1-D transform along rows for `width` columns at once; scratch holds n * width values.
void forward_rows(float* x, std::size_t n, std::size_t stride, std::size_t width, float* scratch) {
  if (n < 2) return;
  lift(x, n, stride, width, 1, kAlpha);
  lift(x, n, stride, width, 0, kBeta);
  lift(x, n, stride, width, 1, kGamma);
  lift(x, n, stride, width, 0, kDelta);
  scale(x, n, stride, width, false);
  const std::size_t lows = (n + 1) / 2;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t to = i % 2 == 0 ? i / 2 : lows + i / 2;
    std::copy_n(x + i * stride, width, scratch + to * width);
  }
  for (std::size_t i = 0; i < n; ++i) std::copy_n(scratch + i * width, width, x + i * stride);
}

void inverse_rows(float* x, std::size_t n, std::size_t stride, std::size_t width, float* scratch) {
  if (n < 2) return;
  const std::size_t lows = (n + 1) / 2;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t from = i % 2 == 0 ? i / 2 : lows + i / 2;
    std::copy_n(x + from * stride, width, scratch + i * width);
  }
  for (std::size_t i = 0; i < n; ++i) std::copy_n(scratch + i * width, width, x + i * stride);
  scale(x, n, stride, width, true);
  lift(x, n, stride, width, 0, -kDelta);
  lift(x, n, stride, width, 1, -kGamma);
  lift(x, n, stride, width, 0, -kBeta);
  lift(x, n, stride, width, 1, -kAlpha);
}

void check(std::span<float> cube, const CubeLayout& c) {
  if (cube.size() != c.dims[0] * c.dims[1] * c.dims[2] || c.levels < 0)
    throw UsageError("wavelet: cube of " + std::to_string(cube.size()) + " values does not match its layout");
  for (std::size_t a = 0; a < 3; ++a)
    if (c.dims[a] < 1 || c.low(c.levels)[a] < 1) throw UsageError("wavelet: too many levels for the cube's extent");
}

// Applies `rows` (forward_rows or inverse_rows) to the low cube entering level l along every axis (order given).
template <class Rows>
void transform_level(float* x, const CubeLayout& c, int l, const std::array<int, 3>& order, std::vector<float>& scratch,
                     Rows rows) {
  const auto e = c.low(l);
  const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
  for (const int axis : order) {
    if (axis == 2) {
      for (std::size_t i = 0; i < e[0]; ++i)
        for (std::size_t j = 0; j < e[1]; ++j) rows(x + i * s0 + j * s1, e[2], 1, 1, scratch.data());
    } else if (axis == 1) {
      for (std::size_t i = 0; i < e[0]; ++i) rows(x + i * s0, e[1], s1, e[2], scratch.data());
    } else {
      for (std::size_t j = 0; j < e[1]; ++j) rows(x + j * s1, e[0], s0, e[2], scratch.data());
    }
  }
}

}  // namespace

void forward_line(std::span<float> x, std::span<float> scratch) {
  if (scratch.size() < x.size()) throw UsageError("wavelet: scratch is shorter than the line");
  forward_rows(x.data(), x.size(), 1, 1, scratch.data());
}

void inverse_line(std::span<float> x, std::span<float> scratch) {
  if (scratch.size() < x.size()) throw UsageError("wavelet: scratch is shorter than the line");
  inverse_rows(x.data(), x.size(), 1, 1, scratch.data());
}

std::array<std::size_t, 3> CubeLayout::low(int l) const {
  std::array<std::size_t, 3> e = dims;
  for (int i = 0; i < l; ++i)
    for (auto& v : e) v = (v + 1) / 2;
  return e;
}

std::array<std::size_t, 2> CubeLayout::range(int l, int o, int axis) const {
  const auto a = std::size_t(axis);
  const std::size_t lo = low(l + 1)[a], hi = low(l)[a];
  if (o == 0) return {0, low(levels)[a]};
  return (o >> axis) & 1 ? std::array<std::size_t, 2>{lo, hi} : std::array<std::size_t, 2>{0, lo};
}

double CubeLayout::synthesis_norm(int l, int o) const {
  // Separable: the product over axes of the 1-D norm of a unit coefficient in the middle of that axis's band.
  double norm = 1;
  for (int axis = 0; axis < 3; ++axis) {
    const std::size_t n = dims[std::size_t(axis)];
    const int steps = o == 0 ? levels : l + 1;
    std::vector<float> x(n, 0.0f), scratch(n);
    const auto r = range(o == 0 ? levels : l, o, axis);
    x[(r[0] + r[1]) / 2] = 1;
    std::vector<std::size_t> ext(std::size_t(steps) + 1, n);
    for (int s = 1; s <= steps; ++s) ext[std::size_t(s)] = (ext[std::size_t(s) - 1] + 1) / 2;
    for (int s = steps - 1; s >= 0; --s) inverse_rows(x.data(), ext[std::size_t(s)], 1, 1, scratch.data());
    double sq = 0;
    for (const float v : x) sq += double(v) * v;
    norm *= std::sqrt(sq);
  }
  return norm;
}

void forward_cube(std::span<float> cube, const CubeLayout& c) {
  check(cube, c);
  std::vector<float> scratch(std::max({c.dims[0], c.dims[1], c.dims[2]}) * c.dims[2]);
  for (int l = 0; l < c.levels; ++l) transform_level(cube.data(), c, l, {2, 1, 0}, scratch, forward_rows);
}

void inverse_cube(std::span<float> cube, const CubeLayout& c) {
  check(cube, c);
  std::vector<float> scratch(std::max({c.dims[0], c.dims[1], c.dims[2]}) * c.dims[2]);
  for (int l = c.levels - 1; l >= 0; --l) transform_level(cube.data(), c, l, {0, 1, 2}, scratch, inverse_rows);
}

}  // namespace specula::codec::wavelet
