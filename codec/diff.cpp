#include "codec/diff.h"

#include <algorithm>
#include <cmath>

#include "core/brdf_geometry.h"
#include "core/colour.h"
#include "core/error.h"

namespace specula::codec {

GridDiff diff_grids(const store::Grid& a, const store::Grid& b, const Environment& env, const DiffOptions& o) {
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError("the first grid has " + a.wavelengths.describe() + ", the second " + b.wavelengths.describe() +
                     "; compare grids on one wavelength grid");
  const std::size_t bands = a.bands(), cells = brdf::kMerlCells;
  if (a.brdf.size() != bands * cells || b.brdf.size() != bands * cells)
    throw UsageError("diff: grid values do not match bands x 90 x 90 x 180");
  GridDiff d;
  double sq = 0, wsq = 0, wref = 0, mx = 0;
  std::uint64_t both = 0, only_a = 0, only_b = 0;
#pragma omp parallel for schedule(static) reduction(+ : sq, wsq, wref, both, only_a, only_b) reduction(max : mx)
  for (long long c = 0; c < static_cast<long long>(cells); ++c) {
    bool va = true, vb = true;
    for (std::size_t k = 0; k < bands; ++k) {
      va &= a.brdf[k * cells + std::size_t(c)] >= 0;
      vb &= b.brdf[k * cells + std::size_t(c)] >= 0;
    }
    if (va != vb) {
      only_a += va;
      only_b += vb;
      continue;
    }
    if (!va) continue;
    ++both;
    const brdf::StdAngles ang = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(std::size_t(c))));
    const double w = std::max(0.0, std::cos(ang.theta_i)) * std::max(0.0, std::cos(ang.theta_o));
    for (std::size_t k = 0; k < bands; ++k) {
      const double x = a.brdf[k * cells + std::size_t(c)] * a.scale, y = b.brdf[k * cells + std::size_t(c)] * b.scale;
      const double e = x - y;
      sq += e * e;
      wsq += w * e * e;
      wref += w * x * x;
      mx = std::max(mx, std::abs(e));
    }
  }
  d.cells = both;
  d.only_a = only_a;
  d.only_b = only_b;
  d.rms = both ? std::sqrt(sq / double(both * bands)) : 0.0;
  d.max_abs = mx;
  d.rel_rms_cos = wref > 0 ? std::sqrt(wsq / wref) : (wsq > 0 ? INFINITY : 0.0);

  d.renders = render_spheres({&a, &b}, env, o.size);
  const auto& r = d.renders;
  d.de00.assign(r.size * r.size, 0.0f);
  std::vector<float> values;
  for (std::size_t p = 0; p < r.size * r.size; ++p) {
    if (!r.covered[p]) continue;
    const Eigen::Vector3d xa(r.xyz[0][3 * p], r.xyz[0][3 * p + 1], r.xyz[0][3 * p + 2]);
    const Eigen::Vector3d xb(r.xyz[1][3 * p], r.xyz[1][3 * p + 1], r.xyz[1][3 * p + 2]);
    const double e = ciede2000(xyz_to_lab(xa, r.white), xyz_to_lab(xb, r.white));
    d.de00[p] = float(e);
    values.push_back(float(e));
  }
  if (!values.empty()) {
    double sum = 0;
    for (const float v : values) sum += v;
    d.de00_mean = sum / double(values.size());
    std::sort(values.begin(), values.end());
    d.de00_p95 = values[std::min(values.size() - 1, std::size_t(std::ceil(0.95 * double(values.size()))) - 1)];
    d.de00_max = values.back();
  }
  return d;
}

}  // namespace specula::codec
