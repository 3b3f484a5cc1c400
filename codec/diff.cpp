#include "specula/codec/diff.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {

De00 de00_of_renders(std::span<const float> a, std::span<const float> b, std::span<const std::uint8_t> covered,
                     const Eigen::Vector3d& white) {
  if (a.size() != 3 * covered.size() || b.size() != a.size())
    throw UsageError("de00: renderings of " + std::to_string(a.size() / 3) + " and " + std::to_string(b.size() / 3) +
                     " pixels for a sphere of " + std::to_string(covered.size()));
  De00 d;
  d.per_pixel.assign(covered.size(), 0.0f);
  std::vector<float> values;
  for (std::size_t p = 0; p < covered.size(); ++p) {
    if (!covered[p]) continue;
    const Eigen::Vector3d xa(a[3 * p], a[3 * p + 1], a[3 * p + 2]), xb(b[3 * p], b[3 * p + 1], b[3 * p + 2]);
    const double e = ciede2000(xyz_to_lab(xa, white), xyz_to_lab(xb, white));
    d.per_pixel[p] = float(e);
    values.push_back(float(e));
  }
  if (!values.empty()) {
    double sum = 0;
    for (const float v : values) sum += v;
    d.mean = sum / double(values.size());
    std::sort(values.begin(), values.end());
    d.p95 = values[std::min(values.size() - 1, std::size_t(std::ceil(0.95 * double(values.size()))) - 1)];
    d.max = values.back();
  }
  return d;
}

GridDiff diff_grids(const store::Grid& a, const store::Grid& b, const Environment& env, const DiffOptions& o) {
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError("the first grid has " + a.wavelengths.describe() + ", the second " + b.wavelengths.describe() +
                     "; compare grids on one wavelength grid");
  const std::size_t bands = a.bands(), cells = brdf::kMerlCells;
  if (a.brdf.size() != bands * cells || b.brdf.size() != bands * cells)
    throw UsageError("diff: grid values do not match bands x 90 x 90 x 180");
  GridDiff d;
  // Fixed blocks of cells summed in order: the sums do not depend on the thread count. Within a block the
  // bands run outermost so that each band plane is read sequentially.
  constexpr std::size_t kBlock = 8100;
  const std::size_t blocks = (cells + kBlock - 1) / kBlock;
  std::vector<double> sq_b(blocks, 0), wsq_b(blocks, 0), wref_b(blocks, 0), mx_b(blocks, 0);
  std::vector<std::uint64_t> both_b(blocks, 0), only_a_b(blocks, 0), only_b_b(blocks, 0);
  struct BlockState {
    std::vector<std::uint8_t> va, vb;
    std::vector<double> w;
  };
  parallel_for(
      blocks,
      [] {
        return BlockState{std::vector<std::uint8_t>(kBlock), std::vector<std::uint8_t>(kBlock),
                          std::vector<double>(kBlock)};
      },
      [&](std::size_t blk, BlockState& st) {
        std::vector<std::uint8_t>&va = st.va, &vb = st.vb;
        std::vector<double>& w = st.w;
        const std::size_t c0 = std::size_t(blk) * kBlock, n = std::min(kBlock, cells - c0);
        std::fill(va.begin(), va.end(), 1);
        std::fill(vb.begin(), vb.end(), 1);
        for (std::size_t k = 0; k < bands; ++k) {
          const float* pa = a.brdf.data() + k * cells + c0;
          const float* pb = b.brdf.data() + k * cells + c0;
          for (std::size_t i = 0; i < n; ++i) {
            va[i] &= pa[i] >= 0;
            vb[i] &= pb[i] >= 0;
          }
        }
        for (std::size_t i = 0; i < n; ++i) {
          if (va[i] != vb[i]) {
            only_a_b[std::size_t(blk)] += va[i];
            only_b_b[std::size_t(blk)] += vb[i];
          }
          va[i] &= vb[i];
          both_b[std::size_t(blk)] += va[i];
          const brdf::StdAngles ang = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(c0 + i)));
          w[i] = std::max(0.0, std::cos(ang.theta_i)) * std::max(0.0, std::cos(ang.theta_o));
        }
        double sq = 0, wsq = 0, wref = 0, mx = 0;
        for (std::size_t k = 0; k < bands; ++k) {
          const float* pa = a.brdf.data() + k * cells + c0;
          const float* pb = b.brdf.data() + k * cells + c0;
          for (std::size_t i = 0; i < n; ++i) {
            if (!va[i]) continue;
            const double x = double(pa[i]) * a.scale, y = double(pb[i]) * b.scale, e = x - y;
            sq += e * e;
            wsq += w[i] * e * e;
            wref += w[i] * x * x;
            mx = std::max(mx, std::abs(e));
          }
        }
        sq_b[std::size_t(blk)] = sq;
        wsq_b[std::size_t(blk)] = wsq;
        wref_b[std::size_t(blk)] = wref;
        mx_b[std::size_t(blk)] = mx;
      },
      4);
  double sq = 0, wsq = 0, wref = 0, mx = 0;
  std::uint64_t both = 0, only_a = 0, only_b = 0;
  for (std::size_t i = 0; i < blocks; ++i) {
    sq += sq_b[i];
    wsq += wsq_b[i];
    wref += wref_b[i];
    mx = std::max(mx, mx_b[i]);
    both += both_b[i];
    only_a += only_a_b[i];
    only_b += only_b_b[i];
  }
  d.cells = both;
  d.only_a = only_a;
  d.only_b = only_b;
  d.rms = both ? std::sqrt(sq / double(both * bands)) : 0.0;
  d.max_abs = mx;
  d.rel_rms_cos = wref > 0 ? std::sqrt(wsq / wref) : (wsq > 0 ? INFINITY : 0.0);

  d.renders = render_spheres({&a, &b}, env, o.size);
  const auto& r = d.renders;
  if (!(r.white.y() > 0))
    throw InputError(
        "environment " + env.description +
        " sends no light to a surface facing the viewer, so there is no white for CIELAB; light the front");
  De00 e = de00_of_renders(r.xyz[0], r.xyz[1], r.covered, r.white);
  d.de00 = std::move(e.per_pixel);
  d.de00_mean = e.mean;
  d.de00_p95 = e.p95;
  d.de00_max = e.max;
  return d;
}

}  // namespace specula::codec
