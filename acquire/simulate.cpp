#include "specula/acquire/simulate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "specula/acquire/filters.h"
#include "specula/acquire/holdout.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/store/io/png_stack.h"

namespace specula::acquire {

namespace fs = std::filesystem;
using std::numbers::pi;

// A smooth CCD quantum efficiency times optics transmission (relative), peaking near 550 nm.
double camera_quantum_efficiency(double nm) { return 0.25 + 0.6 * std::exp(-std::pow((nm - 550) / 140, 2)); }

namespace {

std::vector<double> default_bands() {
  std::vector<double> b;
  for (int nm = 420; nm <= 720; nm += 10) b.push_back(nm);
  return b;
}

// The fine grid the simulator integrates on (nm): passbands, light and BRDF are all sampled on it.
std::vector<double> fine_grid() {
  std::vector<double> nm;
  for (double l = 380; l <= 780.001; l += 2) nm.push_back(l);
  return nm;
}

double quantum_efficiency(double nm) { return camera_quantum_efficiency(nm); }

// Five diffuse targets of smooth known reflectance, as the reference's Labsphere set (red, green, blue, yellow,
// white).
std::vector<CaptureTarget> default_targets(const std::vector<double>& bands) {
  auto logistic = [](double nm, double edge, double width) { return 1 / (1 + std::exp(-(nm - edge) / width)); };
  std::vector<CaptureTarget> t = {{"red", {}}, {"green", {}}, {"blue", {}}, {"yellow", {}}, {"white", {}}};
  for (const double nm : bands) {
    t[0].reflectance.push_back(0.05 + 0.8 * logistic(nm, 600, 12));
    t[1].reflectance.push_back(0.05 + 0.45 * std::exp(-std::pow((nm - 530) / 40, 2)));
    t[2].reflectance.push_back(0.05 + 0.5 * std::exp(-std::pow((nm - 450) / 45, 2)));
    t[3].reflectance.push_back(0.06 + 0.8 * logistic(nm, 520, 15));
    t[4].reflectance.push_back(0.98);
  }
  return t;
}

// Interpolates a target's per-band reflectance onto the fine grid (held constant outside the bands).
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double at) {
  if (at <= x.front()) return y.front();
  if (at >= x.back()) return y.back();
  const auto i = std::size_t(std::upper_bound(x.begin(), x.end(), at) - x.begin());
  const double t = (at - x[i - 1]) / (x[i] - x[i - 1]);
  return y[i - 1] + t * (y[i] - y[i - 1]);
}

// The camera: rate (DN/s, before bias) to a 12-bit value at exposure t, with shot and read noise and clipping.
struct Sensor {
  const SimulatorOptions& o;
  int max_dn;
  std::uint16_t expose(double rate, double t, std::mt19937_64& rng) const {
    double dn = o.dark_dn + rate * t;
    if (o.noise) {
      const double electrons = std::max(0.0, rate * t) * o.electrons_per_dn;
      const double sigma =
          std::sqrt(electrons / (o.electrons_per_dn * o.electrons_per_dn) + o.read_noise_dn * o.read_noise_dn);
      dn += std::normal_distribution<double>(0.0, sigma)(rng);
    }
    return std::uint16_t(std::clamp(std::lround(dn), 0L, long(max_dn)));
  }
};

}  // namespace

void check_simulator(const SimulatorOptions& o) {
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192)
    throw UsageError("simulate-capture: the image must be 16 to 8192 pixels a side");
  check_rig(o.rig);
  if (o.rig.sphere_px > 0.9 * std::min(o.width, o.height))
    throw UsageError(fmt::format("simulate-capture: a sphere {} px across does not fit on a {} x {} image",
                                 o.rig.sphere_px, o.width, o.height));
  for (std::size_t i = 0; i < o.bands.size(); ++i)
    if (!(o.bands[i] >= 400 && o.bands[i] <= 740) || (i && !(o.bands[i] > o.bands[i - 1])))
      throw UsageError("simulate-capture: bands must increase within 400-740 nm");
  if (o.exposures_s.empty()) throw UsageError("simulate-capture: give at least one exposure");
  for (const double t : o.exposures_s)
    if (!(t >= 1e-6 && t <= 60)) throw UsageError("simulate-capture: exposures must be 1 us to 60 s");
  if (!(o.fwhm_blue_nm > 0) || !(o.fwhm_red_nm > 0) || !(o.light_kelvin >= 1000 && o.light_kelvin <= 20000))
    throw UsageError("simulate-capture: passband widths must be positive and the light 1000-20000 K");
  if (!(o.brightness > 0) || !(o.read_noise_dn >= 0) || !(o.electrons_per_dn > 0) || !(o.dark_dn >= 0) ||
      !(o.vignetting >= 0 && o.vignetting < 1))
    throw UsageError(
        "simulate-capture: brightness and gain must be positive, noise and bias >= 0, vignetting in [0, 1)");
  if (o.filters) check_filters(*o.filters, o.bands.empty() ? default_bands() : o.bands, "simulate-capture filters");
  if (o.holdout) holdout_chart(*o.holdout, o.bands.empty() ? default_bands() : o.bands, o.width, o.height);
  if (!(o.lctf_peak > 0 && o.lctf_peak <= 1))
    throw UsageError("simulate-capture: the LCTF's peak transmission is in (0, 1]");
  if (!o.grid && !brdf::material_catalogue().count(o.material))
    throw UsageError("simulate-capture: unknown material '" + o.material +
                     "' (specula synth-brdf lists the analytic materials)");
}

std::vector<std::vector<double>> simulated_response(const SimulatorOptions& o, const std::vector<double>& nm) {
  const std::vector<double> bands = o.bands.empty() ? default_bands() : o.bands;
  std::vector<std::vector<double>> r(bands.size(), std::vector<double>(nm.size(), 0.0));
  const double step = nm.size() > 1 ? nm[1] - nm[0] : 1;
  if (o.filters) {
    r.assign(o.filters->size(), std::vector<double>(nm.size(), 0.0));
    for (std::size_t j = 0; j < o.filters->size(); ++j)
      for (std::size_t k = 0; k < nm.size(); ++k) r[j][k] = quantum_efficiency(nm[k]) * o.filters->at(j, nm[k]);
    return r;
  }
  for (std::size_t j = 0; j < bands.size(); ++j) {
    if (o.passband == Passband::delta) {
      const auto k = std::size_t(std::lround((bands[j] - nm.front()) / step));
      if (k < nm.size()) r[j][k] = quantum_efficiency(bands[j]) / step;
      continue;
    }
    const double fwhm =
        o.fwhm_blue_nm + (o.fwhm_red_nm - o.fwhm_blue_nm) * std::clamp((bands[j] - 420) / 300, 0.0, 1.0);
    const double sigma = fwhm / (2 * std::sqrt(2 * std::log(2.0)));
    for (std::size_t k = 0; k < nm.size(); ++k)
      r[j][k] = quantum_efficiency(nm[k]) * std::exp(-0.5 * std::pow((nm[k] - bands[j]) / sigma, 2)) /
                (sigma * std::sqrt(2 * pi));
  }
  return r;
}

namespace {

// The fraction of light reaching pixel (u, v): 1 at the centre, 1 - vignetting / 2 at the middle of an edge.
double vignetting_factor(const SimulatorOptions& o, int u, int v) {
  const double cx = o.width / 2.0, cy = o.height / 2.0;
  const double dx = (u + 0.5 - cx) / cx, dy = (v + 0.5 - cy) / cy;
  return 1 - o.vignetting * (dx * dx + dy * dy) / 2;
}

// The folders the images of `cap` go in.
void make_image_directories(const fs::path& dir, const Capture& cap, std::size_t lights) {
  for (const char* sub : {"mirror", "flat", "target", "scene"}) fs::create_directories(dir / sub);
  if (!cap.holdout.empty()) fs::create_directories(dir / "holdout");
  for (const auto& t : cap.targets) fs::create_directories(dir / "target" / t.name);
  for (std::size_t l = 0; l < lights; ++l) fs::create_directories(dir / "scene" / fmt::format("L{:03}", l));
}

// UsageError unless every pixel of the sphere lies on the image.
void check_sphere_on_image(const SimulatorOptions& o) {
  const double px = o.width / 2.0, py = o.height / 2.0;
  for (const ScanPixel& p : scan_pixels(o.rig))
    if (p.x + px < 0 || p.x + px >= o.width || p.y + py < 0 || p.y + py >= o.height)
      throw UsageError(
          "simulate-capture: the sphere falls off the image; enlarge the image or bring the sphere to the axis");
}

// Per band: the weights' sum (a white flat field) and, per target (t * B + j), the weights times its reflectance.
std::pair<std::vector<double>, std::vector<double>> flat_and_target_sums(const std::vector<std::vector<double>>& w,
                                                                         const std::vector<double>& bands,
                                                                         const std::vector<CaptureTarget>& targets,
                                                                         const std::vector<double>& nm) {
  const std::size_t B = w.size(), L = nm.size();
  std::vector<double> flat_sum(B, 0.0), target_sum(targets.size() * B, 0.0);
  for (std::size_t j = 0; j < B; ++j) {
    for (std::size_t k = 0; k < L; ++k) flat_sum[j] += w[j][k];
    for (std::size_t t = 0; t < targets.size(); ++t)
      for (std::size_t k = 0; k < L; ++k)
        target_sum[t * B + j] += w[j][k] * interpolate(bands, targets[t].reflectance, nm[k]);
  }
  return {flat_sum, target_sum};
}

// Per held-out patch and channel (p * B + j), the weights times the table's reflectance (linear between its
// wavelengths, constant beyond); then, at B * patches + j, the chart's dark body (a flat 0.05).
std::vector<double> holdout_sums(const std::vector<std::vector<double>>& w, const SimulatorOptions& o,
                                 const std::vector<double>& nm) {
  if (!o.holdout) return {};
  const store::Collection& t = *o.holdout;
  const std::size_t B = w.size(), nb = t.bands(), n = t.size();
  const std::vector<double> x(t.wavelengths.values().begin(), t.wavelengths.values().end());
  std::vector<double> sums((n + 1) * B, 0.0);
  for (std::size_t p = 0; p <= n; ++p) {
    const std::vector<double> y = p < n ? std::vector<double>(t.values.begin() + std::ptrdiff_t(p * nb),
                                                              t.values.begin() + std::ptrdiff_t((p + 1) * nb))
                                        : std::vector<double>(nb, 0.05);
    for (std::size_t j = 0; j < B; ++j)
      for (std::size_t k = 0; k < nm.size(); ++k) sums[p * B + j] += w[j][k] * interpolate(x, y, nm[k]);
  }
  return sums;
}

// Which held-out patch each pixel of the chart shows (the patches' count for the chart's body).
std::vector<std::size_t> holdout_pixels(const Capture& cap) {
  std::vector<std::size_t> patch(std::size_t(cap.width) * std::size_t(cap.height), cap.holdout.size());
  for (std::size_t i = 0; i < cap.holdout.size(); ++i) {
    const HoldoutPatch& p = cap.holdout[i];
    for (int v = p.v0; v < p.v1; ++v)
      for (int u = p.u0; u < p.u1; ++u) patch[std::size_t(v) * std::size_t(cap.width) + std::size_t(u)] = i;
  }
  return patch;
}

// A mirror sphere in the same place: the light's reflection is a small bright spot (a source of 1 degree), found by
// 8 x 8 supersampling of pixel (u, v) where the reflected view ray points at the light at lp.
double mirror_rate(int u, int v, double cx, double cy, const Eigen::Vector3d& lp, const ScanRig& rig,
                   const Eigen::Vector3d& centre, double radius) {
  double sum = 0;
  for (int sy = 0; sy < 8; ++sy)
    for (int sx = 0; sx < 8; ++sx) {
      const Eigen::Vector3d d =
          Eigen::Vector3d((u + (sx + 0.5) / 8 - cx) / rig.focal_px, (v + (sy + 0.5) / 8 - cy) / rig.focal_px, 1)
              .normalized();
      const double b = d.dot(centre), disc = b * b - centre.squaredNorm() + radius * radius;
      if (disc <= 0) continue;
      const Eigen::Vector3d x = (b - std::sqrt(disc)) * d, n = (x - centre) / radius;
      const Eigen::Vector3d r = d - 2 * d.dot(n) * n;
      const double angle = std::acos(std::clamp(r.dot((lp - x).normalized()), -1.0, 1.0)) * 180 / pi;
      sum += std::exp(-0.5 * std::pow(angle / 1.0, 2));
    }
  return 300000 * sum / 64;
}

// Every image is a job with its own seed, so the files do not depend on the thread count.
struct Job {
  CaptureImage image;
  std::uint64_t seed;
};

// The images of a capture in the order they are rendered: silhouette, mirror, flats, targets, then the scene. A
// filter capture's exposures are divided by each filter's gain (its white signal over the LCTF's strongest band).
std::vector<Job> image_jobs(const SimulatorOptions& o, const Capture& cap, const std::vector<double>& gain) {
  const ScanRig& rig = o.rig;
  const std::size_t B = cap.channels();
  std::vector<Job> jobs;
  auto add = [&](ImageKind kind, int light_index, int band, int target, double t, const std::string& file) {
    CaptureImage im{file, kind, light_index, band, target, t};
    jobs.push_back({im, std::uint64_t(o.seed) * 1000003ull + jobs.size()});
  };
  auto time = [&](std::size_t j, double t) { return o.filters ? std::clamp(t / gain[j], 1e-6, 60.0) : t; };
  auto channel = [&](std::size_t j) {
    return o.filters ? fmt::format("F{:02}", j) : fmt::format("B{:03}", int(o.bands[j]));
  };
  auto ms = [](double t) { return fmt::format("{:.6g}ms", t * 1000); };
  add(ImageKind::silhouette, -1, -1, -1, 0.05, "silhouette.png");
  for (std::size_t l = 0; l < rig.lights; ++l)
    add(ImageKind::mirror, int(l), -1, -1, 0.01, fmt::format("mirror/L{:03}.png", l));
  for (std::size_t j = 0; j < B; ++j)
    for (double last = -1; const double e : {0.02, 0.05})
      if (time(j, e) != last)
        last = time(j, e),
        add(ImageKind::flat, -1, int(j), -1, last, fmt::format("flat/{}-{}.png", channel(j), ms(last)));
  for (std::size_t t = 0; t < cap.targets.size(); ++t)
    for (std::size_t j = 0; j < B; ++j)
      for (double last = -1; const double e : {0.02, 0.1, 0.5, 2.0})
        if (time(j, e) != last)
          last = time(j, e), add(ImageKind::target, -1, int(j), int(t), last,
                                 fmt::format("target/{}/{}-{}.png", cap.targets[t].name, channel(j), ms(last)));
  // A filter whose scaled bracket passes the longest exposure (60 s) takes it once: clamped exposures are not
  // repeated. The held-out chart has the scene's bracket.
  for (std::size_t j = 0; j < B && !cap.holdout.empty(); ++j)
    for (double last = -1; const double e : o.exposures_s)
      if (time(j, e) != last)
        last = time(j, e),
        add(ImageKind::holdout, -1, int(j), -1, last, fmt::format("holdout/{}-{}.png", channel(j), ms(last)));
  for (std::size_t l = 0; l < rig.lights; ++l)
    for (std::size_t j = 0; j < B; ++j) {
      double last = -1;
      for (const double e : o.exposures_s) {
        if (time(j, e) == last) continue;
        last = time(j, e);
        add(ImageKind::scene, int(l), int(j), -1, last, fmt::format("scene/L{:03}/{}-{}.png", l, channel(j), ms(last)));
      }
    }
  return jobs;
}

// band_weight[j][k] = L(k) R_j(k) dl / Z, with Z making the strongest band of a white Lambertian (pi f = 1) 1, or
// for a filter capture the strongest band of the LCTF at its peak transmission (options' Gaussian passbands).
std::vector<std::vector<double>> band_weights(const SimulatorOptions& o, const std::vector<double>& nm,
                                              const Eigen::VectorXd& light,
                                              const std::vector<std::vector<double>>& response, double dl) {
  const std::size_t B = response.size(), L = std::size_t(light.size());
  std::vector<std::vector<double>> w(B, std::vector<double>(L));
  double z = 0;
  for (std::size_t j = 0; j < B; ++j) {
    double s = 0;
    for (std::size_t k = 0; k < L; ++k) s += (w[j][k] = light[Eigen::Index(k)] * response[j][k] * dl);
    z = std::max(z, s);
  }
  if (o.filters) {
    SimulatorOptions lctf = o;
    lctf.filters.reset();
    lctf.passband = Passband::gaussian;
    const auto peaks = simulated_response(lctf, nm);
    z = 0;
    for (const auto& r : peaks) {
      double s = 0, peak = 0;
      for (std::size_t k = 0; k < L; ++k) {
        s += light[Eigen::Index(k)] * r[k] * dl;
        peak = std::max(peak, r[k] / quantum_efficiency(nm[k]));
      }
      z = std::max(z, s * o.lctf_peak / peak);
    }
  }
  for (auto& row : w)
    for (double& v : row) v /= z;
  return w;
}

// The manifest of a simulated capture before its images: camera, rig, light, targets, the filter's transmission data
// and the truth (sphere and light directions).
Capture capture_description(const SimulatorOptions& o, const std::vector<double>& nm, const Eigen::VectorXd& light,
                            const std::vector<std::vector<double>>& response, const Eigen::Vector3d& centre,
                            double radius) {
  const ScanRig& rig = o.rig;
  const int W = o.width, H = o.height;
  const double cx = W / 2.0, cy = H / 2.0;
  const std::size_t B = o.bands.size(), L = nm.size();
  Capture cap;
  cap.width = W;
  cap.height = H;
  cap.bit_depth = 12;
  cap.focal_px = rig.focal_px;
  cap.cx = cx;
  cap.cy = cy;
  cap.bands = o.bands;
  cap.sphere_radius_m = sphere_radius(rig);
  cap.light_distance_m = rig.light_distance;
  for (std::size_t l = 0; l < rig.lights; ++l)
    cap.light_angles_deg.push_back(rig.first_light_deg + double(l) * rig.light_step_deg);
  cap.light_spectrum_nm = nm;
  cap.light_spectrum.assign(light.data(), light.data() + light.size());
  cap.targets = default_targets(o.bands);
  if (o.holdout) cap.holdout = holdout_chart(*o.holdout, o.bands, o.width, o.height);
  cap.filters = o.filters;
  // The manufacturer's transmission data: the passbands without the camera's quantum efficiency.
  for (std::size_t j = 0; j < B && !o.filters; ++j) {
    std::vector<double> tn, tv;
    for (std::size_t k = 0; k < L; ++k) {
      const double t = response[j][k] / quantum_efficiency(nm[k]);
      if (t > 1e-6 * (*std::max_element(response[j].begin(), response[j].end()) / quantum_efficiency(o.bands[j])) ||
          std::abs(nm[k] - o.bands[j]) <= 2) {
        tn.push_back(nm[k]);
        tv.push_back(o.passband == Passband::delta ? std::max(0.0, 1 - std::abs(nm[k] - o.bands[j]) / 2) : t);
      }
    }
    cap.lctf_nm.push_back(tn);
    cap.lctf_value.push_back(tv);
  }
  cap.description = fmt::format(
      "simulated: {} sphere, {} lights, {} bands, {} exposures, {}{}", o.material, rig.lights, B, o.exposures_s.size(),
      o.filters ? fmt::format("{} broadband filters", o.filters->size())
                : std::string(o.passband == Passband::delta ? "delta passbands" : "Gaussian passbands"),
      o.noise ? ", noisy" : ", noise-free");
  CaptureTruth truth;
  truth.sphere_centre = {centre.x(), centre.y(), centre.z()};
  truth.sphere_radius = radius;
  truth.material = o.material;
  for (std::size_t l = 0; l < rig.lights; ++l) {
    const Eigen::Vector3d d = (light_position(rig, l) - centre).normalized();
    truth.light_dirs.push_back({d.x(), d.y(), d.z()});
  }
  cap.truth = truth;
  return cap;
}

// Silhouette coverage by 4 x 4 supersampling of the sphere's disc, for edges with sub-pixel information.
std::vector<float> silhouette_coverage(int W, int H, const ScanRig& rig, const Eigen::Vector3d& centre, double radius) {
  const double cx = W / 2.0, cy = H / 2.0;
  std::vector<float> coverage(std::size_t(W * H), 0.0f);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      int hits = 0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx) {
          const Eigen::Vector3d d =
              Eigen::Vector3d((u + (sx + 0.5) / 4 - cx) / rig.focal_px, (v + (sy + 0.5) / 4 - cy) / rig.focal_px, 1)
                  .normalized();
          const double b = d.dot(centre);
          hits += b * b - centre.squaredNorm() + radius * radius > 0;
        }
      coverage[std::size_t(v * W + u)] = float(hits / 16.0);
    }
  return coverage;
}

// The rate of every sphere pixel in every band (DN/s at the brightness scale) for light l: bands x H x W.
template <class Material>
std::vector<float> light_rates(const SimulatorOptions& o, const ScanRig& rig, const std::vector<ScanPixel>& pixels,
                               const Material& material, const std::vector<std::vector<double>>& w, std::size_t l) {
  const std::size_t B = w.size(), L = w.front().size();
  const int W = o.width, H = o.height;
  const double cx = W / 2.0, cy = H / 2.0;
  auto vignette = [&](int u, int v) { return vignetting_factor(o, u, v); };
  const Eigen::Vector3d lp = light_position(rig, l);
  std::vector<float> rate(B * std::size_t(W) * std::size_t(H), 0.0f);
  parallel_for(
      pixels.size(), [&] { return std::vector<double>(L); },
      [&](std::size_t i, std::vector<double>& f) {
        const ScanPixel& p = pixels[i];
        brdf::StdAngles a;
        if (!scan_angles(p, lp, a)) return;
        material.eval(a, f);
        const double d = (lp - p.point).norm();
        const double geometry = std::cos(a.theta_i) * std::pow(rig.light_distance / d, 2) * pi;
        const int u = int(p.x + cx), v = int(p.y + cy);
        const double s = vignette(u, v);
        for (std::size_t j = 0; j < B; ++j) {
          double sum = 0;
          for (std::size_t k = 0; k < L; ++k) sum += w[j][k] * f[k];
          rate[j * std::size_t(W * H) + std::size_t(v * W + u)] = float(o.brightness * s * geometry * sum);
        }
      },
      1024);
  return rate;
}

}  // namespace

Capture simulate_capture(const SimulatorOptions& opt, const fs::path& dir) {
  check_simulator(opt);
  SimulatorOptions o = opt;
  if (o.bands.empty()) o.bands = default_bands();
  check_sphere_on_image(o);
  if (fs::exists(dir) && !fs::is_empty(dir))
    throw UsageError("simulate-capture: " + dir.string() + " exists and is not empty; name a new directory");
  fs::create_directories(dir);

  const std::vector<double> nm = fine_grid();
  const WavelengthGrid fine(nm);
  const Eigen::VectorXd light = blackbody(o.light_kelvin, fine);
  const auto response = simulated_response(o, nm);
  const std::size_t B = response.size();
  const std::vector<std::vector<double>> w = band_weights(o, nm, light, response, nm[1] - nm[0]);
  const auto material = o.grid ? grid_material(o.grid, fine) : brdf::make_material(o.material, fine);

  const int W = o.width, H = o.height;
  const double cx = W / 2.0, cy = H / 2.0;
  const Sensor sensor{o, (1 << 12) - 1};
  auto vignette = [&](int u, int v) { return vignetting_factor(o, u, v); };
  // The scan geometry puts pixel x at image column x + cx (principal point at the image centre).
  ScanRig rig = o.rig;
  const std::vector<ScanPixel> pixels = scan_pixels(rig);
  const Eigen::Vector3d centre(rig.off_axis, rig.off_axis_y, rig.distance);
  const double radius = sphere_radius(rig);

  Capture cap = capture_description(o, nm, light, response, centre, radius);

  // What a flat field and each target send through each channel (the same at every pixel but for vignetting).
  const auto [flat_sum, target_sum] = flat_and_target_sums(w, o.bands, cap.targets, nm);
  const std::vector<Job> jobs = image_jobs(o, cap, flat_sum);
  const std::vector<double> chart_sum = holdout_sums(w, o, nm);
  const std::vector<std::size_t> chart_patch = holdout_pixels(cap);
  make_image_directories(dir, cap, rig.lights);

  std::vector<float> scene_rate;

  const std::vector<float> coverage = silhouette_coverage(W, H, rig, centre, radius);

  auto render = [&](std::size_t first, std::size_t last) {
    parallel_for(last - first, [&](std::size_t k) {
      const Job& job = jobs[first + k];
      const CaptureImage& im = job.image;
      std::mt19937_64 rng(job.seed);
      std::vector<std::uint16_t> img(std::size_t(W * H));
      for (int v = 0; v < H; ++v)
        for (int u = 0; u < W; ++u) {
          const std::size_t p = std::size_t(v * W + u);
          double rate = 0;
          switch (im.kind) {
            case ImageKind::scene:
              rate = scene_rate[std::size_t(im.band) * std::size_t(W * H) + p];
              break;
            case ImageKind::silhouette:
              rate = 60000 * vignette(u, v) * (1 - coverage[p]) + 300 * coverage[p];
              break;
            case ImageKind::flat:
              rate = 50000 * vignette(u, v) * flat_sum[std::size_t(im.band)];
              break;
            case ImageKind::target:
              rate = o.brightness * vignette(u, v) * target_sum[std::size_t(im.target) * B + std::size_t(im.band)];
              break;
            case ImageKind::holdout:
              rate = o.brightness * vignette(u, v) * chart_sum[chart_patch[p] * B + std::size_t(im.band)];
              break;
            case ImageKind::mirror: {
              if (coverage[p] > 0)
                rate = mirror_rate(u, v, cx, cy, light_position(rig, std::size_t(im.light)), rig, centre, radius);
              break;
            }
          }
          img[p] = sensor.expose(rate, im.exposure_s, rng);
        }
      store::write_png_gray16(dir / im.file, std::size_t(W), std::size_t(H), img, true);
    });
  };
  // Calibration images first, then the scene light by light (one light's rates in memory at a time). A light's
  // count of images varies when a filter's clamped exposures were not repeated.
  std::size_t first = 0;
  while (first < jobs.size() && jobs[first].image.kind != ImageKind::scene) ++first;
  render(0, first);
  for (std::size_t l = 0; l < rig.lights; ++l) {
    std::size_t last = first;
    while (last < jobs.size() && jobs[last].image.light == int(l)) ++last;
    scene_rate = light_rates(o, rig, pixels, *material, w, l);
    render(first, last);
    first = last;
  }
  for (const Job& j : jobs) cap.images.push_back(j.image);
  write_manifest(dir, cap);
  return cap;
}

}  // namespace specula::acquire
