#include "specula/codec/suite.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>

#include "specula/codec/spc_eval.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/cie.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

using std::numbers::pi;
constexpr double kDeg = pi / 180;
constexpr double kOffNormalDeg = 60;  // the second view
// The directional lights: (angle from the normal, azimuth) in degrees; 0 once, the others at two azimuths. Seen
// head-on, every pixel of a light at angle a has theta_d = a / 2, so a is an odd number of degrees (31, not 30):
// theta_d then falls on a cell centre of the MERL grid instead of on a boundary, where float rounding would pick the
// cell.
constexpr std::array<std::array<double, 2>, 9> kLights{
    {{0, 0}, {31, 0}, {31, 90}, {61, 0}, {61, 90}, {81, 0}, {81, 90}, {105, 0}, {105, 90}}};
constexpr double kExposurePercentile = 0.99;

// Rank ceil(q n) (1-based) of n sorted values.
float percentile(std::vector<float>& v, double q) {
  if (v.empty()) return 0;
  const std::size_t r = std::min(v.size() - 1, std::size_t(std::ceil(q * double(v.size()))) - 1);
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(r), v.end());
  return v[r];
}

// A cell has data when every band is >= 0 (docs/grid-format.md); holes read as 0 everywhere.
bool cell_has_data(const store::Grid& g, std::size_t cell) {
  for (std::size_t b = 0; b < g.bands(); ++b)
    if (!(g.brdf[b * brdf::kMerlCells + cell] >= 0)) return false;
  return true;
}

void check_grid(const store::Grid& g, const WavelengthGrid& wl, const char* what) {
  if (!g.wavelengths.approx_equal(wl))
    throw InputError(std::string("the ") + what + " has " + g.wavelengths.describe() + ", the lighting suite " +
                     wl.describe() + "; compare grids on one wavelength grid");
  if (g.brdf.size() != g.bands() * brdf::kMerlCells)
    throw UsageError("suite: grid values do not match bands x 90 x 90 x 180");
}

}  // namespace

LightingSuite::LightingSuite(const WavelengthGrid& grid, const SuiteOptions& options) {
  setup(default_environment(grid), options);
}

LightingSuite::LightingSuite(const Environment& env, const SuiteOptions& options) { setup(env, options); }

Eigen::Matrix3d LightingSuite::camera(std::size_t view) const {
  const double a = view == 0 ? 0.0 : kOffNormalDeg * kDeg;
  Eigen::Matrix3d c;  // columns: image x, image y, towards the viewer
  c.col(0) = Eigen::Vector3d(1, 0, 0);
  c.col(1) = Eigen::Vector3d(0, std::cos(a), -std::sin(a));
  c.col(2) = Eigen::Vector3d(0, std::sin(a), std::cos(a));
  return c;
}

Eigen::Vector3d LightingSuite::view_direction(std::size_t view) const { return camera(view).col(2); }

const Eigen::VectorXd& LightingSuite::illuminant(std::size_t condition) const {
  const SuiteCondition& c = conditions_.at(condition);
  if (c.light == "environment") throw UsageError("suite: condition " + c.name + " is lit by the environment");
  return c.light == "A" ? a_ : d65_;
}

void LightingSuite::setup(const Environment& env, const SuiteOptions& o) {
  if (o.size < 16 || o.size > 1024)
    throw UsageError("suite: sphere size " + std::to_string(o.size) + ": give 16 to 1024 pixels");
  wavelengths_ = env.wavelengths;
  size_ = o.size;
  const std::size_t b = wavelengths_.size();
  env_lights_ = codec::environment_lights(env, o.env_regions_w, o.env_regions_h);
  d65_ = specula::illuminant("D65", wavelengths_);
  a_ = specula::illuminant("A", wavelengths_);
  to_xyz_ = SpectrumToXyz(wavelengths_, SpectrumKind::radiance, Eigen::VectorXd::Ones(Eigen::Index(b))).weights();
  for (std::size_t y = 0; y < size_; ++y)
    for (std::size_t x = 0; x < size_; ++x) {
      const double u = 2 * (double(x) + 0.5) / double(size_) - 1, v = 1 - 2 * (double(y) + 0.5) / double(size_);
      if (u * u + v * v < 1) pixels_.push_back(std::uint32_t(y * size_ + x));
    }
  // Geometries: per view the environment, then each directional light; conditions: the environment, then each
  // light in D65 and in A.
  for (std::size_t view = 0; view < 2; ++view) {
    const std::string vname = view == 0 ? "head-on" : "60-off";
    geometry_.push_back({view, true, {}, {}, {}, {}, {}});
    conditions_.push_back({vname + " environment", view, "environment", 0, 0, Eigen::Vector3d::Zero()});
    cond_geometry_.push_back(geometry_.size() - 1);
    for (const auto& [el, az] : kLights) {
      const Eigen::Vector3d d(std::sin(el * kDeg) * std::cos(az * kDeg), std::sin(el * kDeg) * std::sin(az * kDeg),
                              std::cos(el * kDeg));
      geometry_.push_back({view, false, {}, {}, {}, {}, {}});
      for (const char* ill : {"D65", "A"}) {
        conditions_.push_back(
            {vname + " " + ill + " " + std::to_string(int(el)) + "/" + std::to_string(int(az)), view, ill, el, az, d});
        cond_geometry_.push_back(geometry_.size() - 1);
      }
    }
  }
  // Per geometry and pixel, every (light, cell) pair with the light above the pixel's horizon.
  std::vector<std::uint32_t> all_cells;
  for (std::size_t gi = 0; gi < geometry_.size(); ++gi) {
    Geometry& g = geometry_[gi];
    const Eigen::Matrix3d cam = camera(g.view);
    std::vector<Eigen::Vector3d> dirs;  // camera frame
    std::vector<double> lengths;
    if (g.environment) {
      for (std::size_t j = 0; j < env_lights_.count; ++j) {
        dirs.push_back(cam.transpose() * env_lights_.dir[j]);
        lengths.push_back(env_lights_.length[j]);
      }
    } else {
      const SuiteCondition& c = conditions_[std::size_t(std::find(cond_geometry_.begin(), cond_geometry_.end(), gi) -
                                                        cond_geometry_.begin())];
      dirs.push_back(cam.transpose() * c.direction);
      lengths.push_back(1);
    }
    std::vector<float> wi, wo;
    g.offsets.push_back(0);
    g.lit.assign(pixels_.size(), 0);
    for (std::size_t p = 0; p < pixels_.size(); ++p) {
      const double x = 2 * (double(pixels_[p] % size_) + 0.5) / double(size_) - 1;
      const double y = 1 - 2 * (double(pixels_[p] / size_) + 0.5) / double(size_);
      const Eigen::Vector3d n(x, y, std::sqrt(1 - x * x - y * y));
      const Eigen::Vector3d t =
          (std::abs(n.y()) < 0.9 ? Eigen::Vector3d::UnitY().cross(n) : Eigen::Vector3d::UnitX().cross(n)).normalized();
      const Eigen::Vector3d s = n.cross(t);
      for (std::size_t j = 0; j < dirs.size(); ++j) {
        const double c = n.dot(dirs[j]);
        if (c <= 0) continue;
        g.lit[p] = 1;
        wi.insert(wi.end(), {float(t.dot(dirs[j])), float(s.dot(dirs[j])), float(c)});
        wo.insert(wo.end(), {float(t.z()), float(s.z()), float(n.z())});
        g.light.push_back(std::uint32_t(j));
        g.weight.push_back(float(c * lengths[j]));
      }
      g.offsets.push_back(std::uint32_t(g.light.size()));
    }
    g.cell.resize(g.light.size());
    merl_indices(wi, wo, g.cell);
    all_cells.insert(all_cells.end(), g.cell.begin(), g.cell.end());
  }
  cells_ = all_cells;
  std::sort(cells_.begin(), cells_.end());
  cells_.erase(std::unique(cells_.begin(), cells_.end()), cells_.end());
  for (Geometry& g : geometry_)
    for (auto& c : g.cell) c = std::uint32_t(std::lower_bound(cells_.begin(), cells_.end(), c) - cells_.begin());
}

SuiteRenders LightingSuite::render(const store::Grid& grid) const {
  check_grid(grid, wavelengths_, "grid");
  const std::size_t b = wavelengths_.size(), u = cells_.size();
  constexpr std::size_t kChunk = 4096;
  // The cells the suite looks up, cell-major and in 1/sr, holes zero: every value is written below, by the threads
  // that first touch its pages (a target search renders a grid per trial).
  Buffer<float> table;
  table.resize(u * b);
  SuiteRenders out;
  out.cell_valid.assign(u, 0);
  parallel_for((u + kChunk - 1) / kChunk, [&](std::size_t chunk) {
    const std::size_t first = chunk * kChunk, last = std::min(u, first + kChunk);
    for (std::size_t i = first; i < last; ++i) out.cell_valid[i] = 1;
    for (std::size_t k = 0; k < b; ++k) {
      const float* plane = grid.brdf.data() + k * brdf::kMerlCells;
      for (std::size_t i = first; i < last; ++i) {
        const float v = plane[cells_[i]];
        table[i * b + k] = float(double(v) * grid.scale);
        if (!(v >= 0)) out.cell_valid[i] = 0;
      }
    }
    for (std::size_t i = first; i < last; ++i)
      if (!out.cell_valid[i]) std::fill_n(table.begin() + std::ptrdiff_t(i * b), b, 0.0f);
  });
  const Eigen::Matrix<double, 3, Eigen::Dynamic> w_d65 = to_xyz_ * d65_.asDiagonal(), w_a = to_xyz_ * a_.asDiagonal();
  out.xyz.assign(conditions_.size(), std::vector<float>(3 * pixels_.size(), 0.0f));
  std::vector<std::array<std::size_t, 2>> conds(geometry_.size(), {SIZE_MAX, SIZE_MAX});
  for (std::size_t c = 0; c < conditions_.size(); ++c) {
    auto& slot = conds[cond_geometry_[c]];
    (slot[0] == SIZE_MAX ? slot[0] : slot[1]) = c;
  }
  const std::size_t np = pixels_.size();
  // Every (geometry, pixel) on any thread; each pixel sums its pairs in one fixed order.
  parallel_for(
      geometry_.size() * np, [&] { return Eigen::VectorXd(static_cast<Eigen::Index>(b)); },
      [&](std::size_t i, Eigen::VectorXd& l) {
        const Geometry& g = geometry_[i / np];
        const std::size_t p = i % np;
        l.setZero();
        for (std::uint32_t q = g.offsets[p]; q < g.offsets[p + 1]; ++q) {
          const float* f = table.data() + std::size_t(g.cell[q]) * b;
          const double wgt = g.weight[q];
          if (g.environment) {
            const double* power = env_lights_.power.data() + g.light[q];
            for (std::size_t k = 0; k < b; ++k) l[Eigen::Index(k)] += double(f[k]) * power[k * env_lights_.count] * wgt;
          } else {
            for (std::size_t k = 0; k < b; ++k) l[Eigen::Index(k)] += double(f[k]) * wgt;
          }
        }
        const auto& cs = conds[i / np];
        for (const std::size_t c : cs) {
          if (c == SIZE_MAX) continue;
          const Eigen::Vector3d xyz = g.environment ? Eigen::Vector3d(to_xyz_ * l)
                                                    : Eigen::Vector3d((conditions_[c].light == "A" ? w_a : w_d65) * l);
          for (std::size_t k = 0; k < 3; ++k) out.xyz[c][3 * p + k] = float(xyz[Eigen::Index(k)]);
        }
      },
      64);
  return out;
}

SuiteDiff LightingSuite::compare(const SuiteRenders& ref, const SuiteRenders& test, bool keep_maps) const {
  if (ref.xyz.size() != conditions_.size() || test.xyz.size() != conditions_.size() ||
      ref.cell_valid.size() != cells_.size() || test.cell_valid.size() != cells_.size())
    throw UsageError("suite compare: renderings are not of this suite");
  const std::size_t np = pixels_.size(), nc = conditions_.size();
  SuiteDiff d;
  d.conditions.resize(nc);
  std::vector<std::vector<float>> values(nc), maps(nc);
  parallel_for(nc, [&](std::size_t c) {
    const Geometry& g = geometry_[cond_geometry_[c]];
    const std::vector<float>& a = ref.xyz[c];
    const std::vector<float>& t = test.xyz[c];
    // Exposure: the white of the light (a white Lambertian surface facing it; for the environment, facing the
    // viewer), scaled so that its Y is the reference's 99th-percentile luminance over the compared pixels.
    Eigen::Vector3d white;
    if (g.environment) {
      const Eigen::Matrix3d cam = camera(g.view);
      Eigen::VectorXd e = Eigen::VectorXd::Zero(Eigen::Index(wavelengths_.size()));
      for (std::size_t j = 0; j < env_lights_.count; ++j) {
        const double z = (cam.transpose() * env_lights_.dir[j]).z();
        if (z > 0)
          for (std::size_t k = 0; k < wavelengths_.size(); ++k)
            e[Eigen::Index(k)] += env_lights_.power[k * env_lights_.count + j] * env_lights_.length[j] * z / pi;
      }
      white = to_xyz_ * e;
    } else {
      white = to_xyz_ * illuminant(c) / pi;
    }
    // Compared: lit pixels with at least one cell the reference has data for.
    std::vector<std::uint8_t> seen(np, 0);
    for (std::size_t p = 0; p < np; ++p)
      for (std::uint32_t q = g.offsets[p]; q < g.offsets[p + 1] && !seen[p]; ++q) seen[p] = ref.cell_valid[g.cell[q]];
    std::vector<float> lum;
    for (std::size_t p = 0; p < np; ++p)
      if (seen[p]) lum.push_back(a[3 * p + 1]);
    const double y = percentile(lum, kExposurePercentile);
    if (y > 0 && white.y() > 0) white *= y / white.y();
    ConditionDiff& cd = d.conditions[c];
    cd.white = white;
    if (keep_maps) maps[c].assign(np, 0.0f);
    for (std::size_t p = 0; p < np; ++p) {
      if (!g.lit[p]) continue;
      if (!seen[p]) {
        ++cd.unseen_pixels;
        continue;
      }
      const Eigen::Vector3d xa(a[3 * p], a[3 * p + 1], a[3 * p + 2]), xb(t[3 * p], t[3 * p + 1], t[3 * p + 2]);
      const float e = float(ciede2000(xyz_to_lab(xa, white), xyz_to_lab(xb, white)));
      values[c].push_back(e);
      if (keep_maps) maps[c][p] = e;
      bool hole = false;
      for (std::uint32_t q = g.offsets[p]; q < g.offsets[p + 1] && !hole; ++q)
        hole = ref.cell_valid[g.cell[q]] && !test.cell_valid[g.cell[q]];
      cd.hole_pixels += hole;
    }
    cd.pixels = values[c].size();
    double sum = 0;
    for (const float v : values[c]) sum += v;
    cd.de00_mean = cd.pixels ? sum / double(cd.pixels) : 0.0;
    std::vector<float> sorted = values[c];
    cd.de00_p95 = percentile(sorted, 0.95);
    cd.de00_max = sorted.empty() ? 0.0 : *std::max_element(sorted.begin(), sorted.end());
  });
  std::vector<float> pooled;
  double sum = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    for (const float v : values[c]) sum += v;
    pooled.insert(pooled.end(), values[c].begin(), values[c].end());
    d.pixels += d.conditions[c].pixels;
    d.hole_pixels += d.conditions[c].hole_pixels;
    d.unseen_pixels += d.conditions[c].unseen_pixels;
    if (d.conditions[c].de00_mean > d.conditions[d.worst].de00_mean) d.worst = c;
  }
  d.de00_mean = pooled.empty() ? 0.0 : sum / double(pooled.size());
  d.de00_max = pooled.empty() ? 0.0 : *std::max_element(pooled.begin(), pooled.end());
  d.de00_p95 = percentile(pooled, 0.95);
  if (keep_maps) d.de00 = std::move(maps);
  return d;
}

std::array<double, 4> suite_albedo(const store::Grid& grid) {
  if (grid.brdf.size() != grid.bands() * brdf::kMerlCells)
    throw UsageError("albedo: grid values do not match bands x 90 x 90 x 180");
  constexpr std::size_t kU = 128, kPhi = 180;
  const std::size_t b = grid.bands();
  const Eigen::VectorXd e = illuminant("D65", grid.wavelengths);
  const Eigen::RowVectorXd ybar =
      SpectrumToXyz(grid.wavelengths, SpectrumKind::radiance, Eigen::VectorXd::Ones(Eigen::Index(b))).weights().row(1);
  const Eigen::RowVectorXd wy = ybar.cwiseProduct(e.transpose());
  std::array<double, 4> out{};
  for (std::size_t a = 0; a < kSuiteAlbedoAngles.size(); ++a) {
    const double ti = kSuiteAlbedoAngles[a] * kDeg;
    std::vector<float> wi, wo;
    for (std::size_t iu = 0; iu < kU; ++iu)
      for (std::size_t ip = 0; ip < kPhi; ++ip) {
        const double mu = std::sqrt((double(iu) + 0.5) / double(kU)), phi = 2 * pi * (double(ip) + 0.5) / double(kPhi);
        const double st = std::sqrt(1 - mu * mu);
        wi.insert(wi.end(), {float(std::sin(ti)), 0.0f, float(std::cos(ti))});
        wo.insert(wo.end(), {float(st * std::cos(phi)), float(st * std::sin(phi)), float(mu)});
      }
    std::vector<std::uint32_t> cells(kU * kPhi);
    merl_indices(wi, wo, cells);
    Eigen::VectorXd rho = Eigen::VectorXd::Zero(Eigen::Index(b));
    for (const std::uint32_t c : cells) {
      if (!cell_has_data(grid, c)) continue;
      for (std::size_t k = 0; k < b; ++k) rho[Eigen::Index(k)] += double(grid.brdf[k * brdf::kMerlCells + c]);
    }
    rho *= grid.scale * 0.5 / double(kU) * 2 * pi / double(kPhi);  // d(projected solid angle) = du/2 dphi
    out[a] = wy.dot(rho) / wy.sum();
  }
  return out;
}

void suite_value_metrics(const store::Grid& a, const store::Grid& b, SuiteDiff& d) {
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError("the first grid has " + a.wavelengths.describe() + ", the second " + b.wavelengths.describe() +
                     "; compare grids on one wavelength grid");
  check_grid(a, a.wavelengths, "first grid");
  check_grid(b, a.wavelengths, "second grid");
  constexpr std::size_t kBlock = 8100;
  const std::size_t blocks = (brdf::kMerlCells + kBlock - 1) / kBlock, bands = a.bands();
  std::vector<double> wsq(blocks, 0), wref(blocks, 0);
  std::vector<std::uint64_t> cells(blocks, 0), holes(blocks, 0), extra(blocks, 0);
  parallel_for(blocks, [&](std::size_t blk) {
    for (std::size_t c = blk * kBlock; c < std::min(brdf::kMerlCells, (blk + 1) * kBlock); ++c) {
      const bool va = cell_has_data(a, c), vb = cell_has_data(b, c);
      extra[blk] += !va && vb;
      if (!va) continue;
      ++cells[blk];
      holes[blk] += !vb;
      const brdf::StdAngles ang = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(c)));
      const double w = std::max(0.0, std::cos(ang.theta_i)) * std::max(0.0, std::cos(ang.theta_o));
      for (std::size_t k = 0; k < bands; ++k) {
        const double x = double(a.brdf[k * brdf::kMerlCells + c]) * a.scale;
        const double y = vb ? double(b.brdf[k * brdf::kMerlCells + c]) * b.scale : 0.0;
        wsq[blk] += w * (x - y) * (x - y);
        wref[blk] += w * x * x;
      }
    }
  });
  double s = 0, r = 0;
  d.cells = d.hole_cells = d.extra_cells = 0;
  for (std::size_t i = 0; i < blocks; ++i) {
    s += wsq[i];
    r += wref[i];
    d.cells += cells[i];
    d.hole_cells += holes[i];
    d.extra_cells += extra[i];
  }
  d.rel_rms_cos = r > 0 ? std::sqrt(s / r) : (s > 0 ? INFINITY : 0.0);
  d.albedo_a = suite_albedo(a);
  d.albedo_b = suite_albedo(b);
  for (std::size_t i = 0; i < d.albedo_a.size(); ++i)
    d.albedo_rel_error[i] = d.albedo_a[i] > 0 ? std::abs(d.albedo_b[i] - d.albedo_a[i]) / d.albedo_a[i]
                                              : (d.albedo_b[i] > 0 ? INFINITY : 0.0);
}

SuiteDiff suite_diff(const store::Grid& a, const store::Grid& b, const LightingSuite& suite, bool keep_maps) {
  check_grid(a, suite.wavelengths(), "first grid");
  check_grid(b, suite.wavelengths(), "second grid");
  SuiteDiff d = suite.compare(suite.render(a), suite.render(b), keep_maps);
  suite_value_metrics(a, b, d);
  return d;
}

std::string suite_json(const SuiteDiff& d, const LightingSuite& suite) {
  using json = nlohmann::ordered_json;
  auto finite = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json conditions = json::array();
  for (std::size_t c = 0; c < d.conditions.size(); ++c) {
    const SuiteCondition& sc = suite.conditions().at(c);
    const ConditionDiff& cd = d.conditions[c];
    conditions.push_back({{"name", sc.name},
                          {"view", sc.view == 0 ? "head-on" : "60 deg off the normal"},
                          {"light", sc.light},
                          {"elevation_deg", sc.elevation_deg},
                          {"azimuth_deg", sc.azimuth_deg},
                          {"de00_mean", cd.de00_mean},
                          {"de00_p95", cd.de00_p95},
                          {"de00_max", cd.de00_max},
                          {"pixels", cd.pixels},
                          {"hole_pixels", cd.hole_pixels},
                          {"unseen_pixels", cd.unseen_pixels}});
  }
  json albedo = json::array();
  for (std::size_t i = 0; i < kSuiteAlbedoAngles.size(); ++i)
    albedo.push_back({{"theta_i_deg", kSuiteAlbedoAngles[i]},
                      {"reference", d.albedo_a[i]},
                      {"compared", d.albedo_b[i]},
                      {"relative_error", finite(d.albedo_rel_error[i])}});
  const json j = {{"suite", {{"conditions", d.conditions.size()}, {"size", suite.size()}}},
                  {"de00_mean", d.de00_mean},
                  {"de00_p95", d.de00_p95},
                  {"de00_max", d.de00_max},
                  {"pixels", d.pixels},
                  {"hole_pixels", d.hole_pixels},
                  {"unseen_pixels", d.unseen_pixels},
                  {"worst_condition", d.conditions.empty() ? "" : suite.conditions().at(d.worst).name},
                  {"worst_de00_mean", d.conditions.empty() ? 0.0 : d.conditions[d.worst].de00_mean},
                  {"cells", d.cells},
                  {"hole_cells", d.hole_cells},
                  {"extra_cells", d.extra_cells},
                  {"rel_rms_cos", finite(d.rel_rms_cos)},
                  {"albedo", albedo},
                  {"conditions", conditions}};
  return j.dump();
}

}  // namespace specula::codec
