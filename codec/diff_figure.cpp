#include "specula/codec/diff_figure.h"

#include <algorithm>
#include <string>

#include "specula/codec/environment.h"
#include "specula/codec/render.h"
#include "specula/codec/suite.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

constexpr std::uint8_t kBackground = 24;

// The size x size picture `src` (3 bytes a pixel) copied into `dst` (`stride` pixels wide) at column x0.
void place(std::span<const std::uint8_t> src, std::size_t size, std::span<std::uint8_t> dst, std::size_t stride,
           std::size_t x0) {
  for (std::size_t y = 0; y < size; ++y)
    std::copy_n(src.begin() + std::ptrdiff_t(3 * y * size), 3 * size,
                dst.begin() + std::ptrdiff_t(3 * (y * stride + x0)));
}

}  // namespace

Picture diff_panel(const SphereRenders& renders, std::span<const float> de00, bool map_only) {
  const std::size_t n = renders.size;
  if (de00.size() != n * n || renders.covered.size() != n * n)
    throw UsageError("diff_panel: " + std::to_string(de00.size()) + " CIEDE2000 values for a " + std::to_string(n) +
                     "-pixel sphere; give one per pixel");
  Picture p;
  p.width = (map_only ? 1 : 3) * n;
  p.height = n;
  p.srgb8.assign(3 * p.width * n, kBackground);
  if (!map_only) {
    std::vector<double> linear(3 * n * n);
    std::vector<std::uint8_t> srgb(3 * n * n);
    for (std::size_t i = 0; i < 2; ++i) {
      linear_srgb(renders, "the lighting", i, linear);
      encode_srgb8(std::span<const double>(linear), renders.covered, 0.0, srgb, kBackground);
      place(srgb, n, p.srgb8, p.width, i * n);
    }
  }
  const std::size_t x0 = map_only ? 0 : 2 * n;
  for (std::size_t q = 0; q < n * n; ++q) {
    if (!renders.covered[q]) continue;
    const Rgb8 c = heat(std::min(1.0, de00[q] / 2.0));
    std::copy(c.begin(), c.end(), p.srgb8.begin() + std::ptrdiff_t(3 * ((q / n) * p.width + x0 + q % n)));
  }
  return p;
}

Picture suite_panel(const LightingSuite& suite, const SuiteRenders& a, const SuiteRenders& b, const SuiteDiff& d,
                    bool map_only) {
  const std::size_t n = suite.size(), c = d.worst;
  if (d.de00.size() <= c) throw UsageError("suite_panel: the comparison kept no per-pixel maps (keep_maps)");
  SphereRenders r;
  r.size = n;
  r.covered.assign(n * n, 0);
  r.white = d.conditions[c].white;
  r.xyz.assign(2, std::vector<float>(3 * n * n, 0.0f));
  std::vector<float> de00(n * n, 0.0f);
  const auto& px = suite.pixels();
  for (std::size_t i = 0; i < px.size(); ++i) {
    r.covered[px[i]] = 1;
    de00[px[i]] = d.de00[c][i];
    for (std::size_t k = 0; k < 3; ++k)
      r.xyz[0][3 * px[i] + k] = a.xyz[c][3 * i + k], r.xyz[1][3 * px[i] + k] = b.xyz[c][3 * i + k];
  }
  return diff_panel(r, de00, map_only);
}

}  // namespace specula::codec
