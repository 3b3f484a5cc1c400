#include "specula/acquire/study.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// The isotropic configuration a pixel shows: its normal, the light and the viewer.
bool pixel_angles(const Eigen::Vector3d& n, const Eigen::Vector3d& l, brdf::IsoAngles& a) {
  const Eigen::Vector3d v(0, 0, 1);
  const double ci = n.dot(l), co = n.dot(v);
  if (ci <= 0 || co <= 0) return false;
  const Eigen::Vector3d lp = l - ci * n, vp = v - co * n;
  const double norm = lp.norm() * vp.norm();
  a.theta_i = std::acos(std::min(1.0, ci));
  a.theta_o = std::acos(std::min(1.0, co));
  a.phi_d = norm > 1e-12 ? std::acos(std::clamp(lp.dot(vp) / norm, -1.0, 1.0)) : 0.0;
  return true;
}

template <class Fn>
void for_each_pixel(std::size_t size, Fn&& fn) {
  for (std::size_t row = 0; row < size; ++row)
    for (std::size_t col = 0; col < size; ++col) {
      const double x = (double(col) + 0.5) / double(size) * 2 - 1, y = 1 - (double(row) + 0.5) / double(size) * 2;
      const double r2 = x * x + y * y;
      if (r2 >= 1) continue;
      fn(row * size + col, Eigen::Vector3d(x, y, std::sqrt(1 - r2)));
    }
}

}  // namespace

SphereRender render_sphere(std::size_t size, const Eigen::Vector3d& light, const IsoBrdf& f) {
  if (size == 0 || size > 16384) throw UsageError("render_sphere: the size must be 1 to 16384 pixels");
  if (!(light.norm() > 0) || !light.allFinite())
    throw UsageError("render_sphere: the light direction must be non-zero");
  const Eigen::Vector3d l = light.normalized();
  SphereRender out;
  out.size = size;
  out.value.assign(size * size, 0.0);
  out.covered.assign(size * size, 0);
  for_each_pixel(size, [&](std::size_t p, const Eigen::Vector3d& n) {
    out.covered[p] = 1;
    brdf::IsoAngles a;
    double v = 0;
    if (pixel_angles(n, l, a) && f(a, v)) out.value[p] = pi * v * std::cos(a.theta_i);
  });
  return out;
}

std::size_t merl_lookup_cell(const brdf::IsoAngles& a) {
  return brdf::merl_index(brdf::merl_cell(brdf::StdAngles{a.theta_i, 0.0, a.theta_o, a.phi_d}));
}

StudyOutput resampling_study(const brdf::SpectralModel& model, std::size_t band, std::span<const double> angles,
                             std::span<const float> values, const StudyOptions& o) {
  const std::size_t bands = model.bands();
  if (band >= bands)
    throw UsageError("resampling_study: band " + std::to_string(band) + " of " + std::to_string(bands));
  if (angles.size() % 4 != 0 || values.size() != angles.size() / 4 * bands)
    throw UsageError("resampling_study: angles must be n x 4 and values n x bands");
  if (o.ks.empty()) throw UsageError("resampling_study: give at least one k");
  std::vector<double> f(bands);
  auto truth = [&](const brdf::StdAngles& a) {
    model.eval(a, f);
    return f[band];
  };
  StudyOutput out;
  out.truth = render_sphere(o.render_size, o.light, [&](const brdf::IsoAngles& a, double& v) {
    v = truth({a.theta_i, 0.0, a.theta_o, a.phi_d});
    return true;
  });
  // The cells the render reads.
  std::vector<std::size_t> cells;
  for_each_pixel(o.render_size, [&](std::size_t, const Eigen::Vector3d& n) {
    brdf::IsoAngles a;
    if (pixel_angles(n, o.light.normalized(), a)) cells.push_back(merl_lookup_cell(a));
  });
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  auto render_cells = [&](const std::vector<double>& cell_value) {
    return render_sphere(o.render_size, o.light, [&](const brdf::IsoAngles& a, double& v) {
      const auto at = std::lower_bound(cells.begin(), cells.end(), merl_lookup_cell(a)) - cells.begin();
      v = cell_value[std::size_t(at)];
      return !std::isnan(v);
    });
  };
  auto compare = [&](const SphereRender& r, StudyResult& row) {
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t p = 0; p < r.value.size(); ++p) {
      if (!r.covered[p]) continue;
      const double e = std::abs(r.value[p] - out.truth.value[p]);
      sum += e;
      row.max_error = std::max(row.max_error, e);
      ++n;
    }
    row.l1 = n ? sum / double(n) : 0.0;
  };
  std::vector<double> cell_value(cells.size());
  for (std::size_t c = 0; c < cells.size(); ++c)
    cell_value[c] = truth(brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cells[c]))));
  out.grid_truth = render_cells(cell_value);
  StudyResult grid_row;
  compare(out.grid_truth, grid_row);
  out.grid_l1 = grid_row.l1;

  const std::size_t n = angles.size() / 4;
  std::vector<float> column(n);
  for (std::size_t i = 0; i < n; ++i) column[i] = values[i * bands + band];
  const brdf::MemorySamples src(angles, column, 1);
  for (const brdf::Mapping m : {brdf::Mapping::halfdiff, brdf::Mapping::marschner, brdf::Mapping::standard}) {
    const auto tree = std::make_shared<const brdf::SampleTree>(src, m);
    for (const std::size_t k : o.ks)
      for (const brdf::Weights w : {brdf::Weights::mean, brdf::Weights::shepard}) {
        if (k == 1 && w == brdf::Weights::shepard) continue;
        check_interrupt();
        const brdf::Resampler r(tree, column, 1,
                                {.mapping = m, .k = k, .weights = w, .power = 1, .max_gap = o.max_gap});
        std::vector<double> v(cells.size());
        parallel_for(
            cells.size(),
            [&](std::size_t c) {
              float x = 0;
              const bool has = r.predict(brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cells[c]))),
                                         std::span<float>(&x, 1));
              v[c] = has ? double(x) : std::numeric_limits<double>::quiet_NaN();
            },
            64);
        StudyResult row{.mapping = m, .k = k, .weights = w};
        SphereRender render = render_cells(v);
        compare(render, row);
        for (std::size_t p = 0; p < render.value.size(); ++p) {
          if (!render.covered[p]) continue;
          brdf::IsoAngles a;
          const double x = (double(p % o.render_size) + 0.5) / double(o.render_size) * 2 - 1;
          const double y = 1 - (double(p / o.render_size) + 0.5) / double(o.render_size) * 2;
          const Eigen::Vector3d nrm(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y)));
          if (pixel_angles(nrm, o.light.normalized(), a)) {
            const auto at = std::lower_bound(cells.begin(), cells.end(), merl_lookup_cell(a)) - cells.begin();
            row.pixels_without_data += std::isnan(v[std::size_t(at)]);
          }
        }
        out.rows.push_back(row);
        out.renders.push_back(std::move(render));
      }
  }
  return out;
}

}  // namespace specula::acquire
