#include "specula/acquire/pipeline.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "specula/acquire/filters.h"
#include "specula/acquire/sample_noise.h"
#include "specula/acquire/scan.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/store/io/png_stack.h"

namespace specula::acquire {

namespace fs = std::filesystem;
using std::numbers::pi;

namespace {

GreyImage load_grey(const Capture& cap, const fs::path& dir, const std::string& file) {
  const fs::path p = dir / file;
  const store::PngImage png = store::read_png(p);
  if (png.channels != 1 || png.width != std::size_t(cap.width) || png.height != std::size_t(cap.height))
    throw InputError(p.string() + ": " + std::to_string(png.width) + " x " + std::to_string(png.height) + " with " +
                     std::to_string(png.channels) + " channels; the manifest says grey " + std::to_string(cap.width) +
                     " x " + std::to_string(cap.height));
  return {cap.width, cap.height, std::vector<float>(png.samples.begin(), png.samples.end())};
}

const CaptureImage& only_image(const Capture& cap, ImageKind kind, int light, const fs::path& dir) {
  for (const auto& im : cap.images)
    if (im.kind == kind && (light < 0 || im.light == light)) return im;
  throw InputError((dir / "manifest.json").string() + ": no " + kind_name(kind) + " image" +
                   (light >= 0 ? " for light " + std::to_string(light) : std::string()));
}

}  // namespace

namespace {

// Decodes `files` (all of one size) on all threads; an error names its file.
std::vector<std::vector<std::uint16_t>> decode_all(const Capture& cap, const fs::path& dir,
                                                   const std::vector<const CaptureImage*>& files) {
  std::vector<std::vector<std::uint16_t>> pixels(files.size());
  parallel_for(files.size(), [&](std::size_t i) {
    const CaptureImage& im = *files[i];
    store::PngImage png = store::read_png(dir / im.file);
    if (png.channels != 1 || png.width != std::size_t(cap.width) || png.height != std::size_t(cap.height))
      throw InputError((dir / im.file).string() + ": not a grey " + std::to_string(cap.width) + " x " +
                       std::to_string(cap.height) + " image");
    pixels[i] = std::move(png.samples);
  });
  return pixels;
}

HdrImage merge_files(const Capture& cap, const fs::path& dir, const std::vector<const CaptureImage*>& files,
                     const std::vector<std::vector<std::uint16_t>>& pixels, ImageKind kind, int band,
                     const HdrOptions& o) {
  if (files.empty())
    throw InputError((dir / "manifest.json").string() + ": no " + kind_name(kind) + " exposures for band " +
                     std::to_string(band));
  std::vector<std::span<const std::uint16_t>> views(pixels.begin(), pixels.end());
  std::vector<double> times;
  for (const auto* im : files) times.push_back(im->exposure_s);
  return merge_exposures(views, times, cap.bit_depth, o);
}

bool in_series(const CaptureImage& im, ImageKind kind, int light, int target, int band) {
  return im.kind == kind && (band < 0 || im.band == band) && (kind != ImageKind::scene || im.light == light) &&
         (kind != ImageKind::target || im.target == target);
}

// Every band of one light position, merged; the light's images are decoded as one batch on all threads.
std::vector<HdrImage> merge_light(const Capture& cap, const fs::path& dir, int light, const HdrOptions& o) {
  std::vector<const CaptureImage*> files;
  for (const auto& im : cap.images)
    if (in_series(im, ImageKind::scene, light, -1, -1)) files.push_back(&im);
  auto pixels = decode_all(cap, dir, files);
  std::vector<HdrImage> out;
  for (int b = 0; b < int(cap.channels()); ++b) {
    std::vector<const CaptureImage*> f;
    std::vector<std::vector<std::uint16_t>> p;
    for (std::size_t i = 0; i < files.size(); ++i)
      if (files[i]->band == b) f.push_back(files[i]), p.push_back(std::move(pixels[i]));
    out.push_back(merge_files(cap, dir, f, p, ImageKind::scene, b, o));
  }
  return out;
}

}  // namespace

HdrImage merge_series(const Capture& cap, const fs::path& dir, ImageKind kind, int light, int target, int band,
                      const HdrOptions& o) {
  std::vector<const CaptureImage*> files;
  for (const auto& im : cap.images)
    if (in_series(im, kind, light, target, band)) files.push_back(&im);
  return merge_files(cap, dir, files, decode_all(cap, dir, files), kind, band, o);
}

HdrSummary write_hdr_images(const Capture& cap, const fs::path& dir, const HdrOptions& o, store::StoreWriter& out) {
  if (cap.filters)
    throw InputError((dir / "manifest.json").string() + ": a filter capture's " + std::to_string(cap.filters->size()) +
                     " channels are filters, not wavelength bands, and the store's HDR images are cubes on "
                     "wavelengths; acquire run merges them and reconstructs the spectra");
  HdrSummary sum;
  const std::size_t W = std::size_t(cap.width), H = std::size_t(cap.height), B = cap.bands.size();
  sum.lights = cap.light_angles_deg.size();
  sum.bands = B;
  sum.pixels = W * H * sum.lights;
  Progress progress("hdr", sum.lights);
  for (std::size_t l = 0; l < sum.lights; ++l) {
    check_interrupt();
    store::Cube cube;
    cube.resize(H, W, B);
    cube.wavelengths = WavelengthGrid(cap.bands);
    cube.units = "DN/s";
    cube.provenance.source_file = dir.string();
    cube.provenance.importer = "acquire-hdr";
    cube.mask.assign(H * W, 1);
    const std::vector<HdrImage> hdr = merge_light(cap, dir, int(l), o);
    for (std::size_t b = 0; b < B; ++b)
      for (std::size_t p = 0; p < H * W; ++p) {
        cube.data[p * B + b] = hdr[b].rate[p];
        ++sum.status[std::size_t(hdr[b].status[p])];
        if (hdr[b].status[p] != HdrStatus::ok && hdr[b].status[p] != HdrStatus::single) cube.mask[p] = 0;
      }
    for (const auto m : cube.mask) sum.valid_pixels += m;
    char name[32];
    std::snprintf(name, sizeof name, "hdr-L%03zu", l);
    out.add_image(name, cube);
    progress.advance();
  }
  return sum;
}

namespace {

SpectralCalibration calibrate_filters(const Capture& cap, const fs::path& dir, const Tabulated& light,
                                      const PipelineOptions& o, const Eigen::MatrixXd& fit_h,
                                      const Eigen::MatrixXd& fit_r);
}  // namespace

Eigen::VectorXd filter_reading_noise(const Capture& cap, const fs::path& dir, const SensorNoise& noise,
                                     const HdrOptions& o, std::size_t lights) {
  const std::size_t K = cap.channels(), L = cap.light_angles_deg.size(), n = std::min(L, lights);
  if (n == 0) throw UsageError("filter_reading_noise: a capture with lights, and lights >= 1");
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Eigen::Index(K));
  std::uint64_t pixels = 0;
  for (std::size_t i = 0; i < n; ++i) {
    check_interrupt();
    const int l = int(n == 1 ? 0 : i * (L - 1) / (n - 1));
    std::vector<std::vector<double>> times(K);
    for (const auto& im : cap.images)
      if (im.kind == ImageKind::scene && im.light == l) times[std::size_t(im.band)].push_back(im.exposure_s);
    const std::vector<HdrImage> hdr = merge_light(cap, dir, l, o);
    for (std::size_t p = 0; p < hdr[0].pixels; ++p) {
      bool valid = true;
      for (std::size_t k = 0; k < K && valid; ++k)
        valid = (hdr[k].status[p] == HdrStatus::ok || hdr[k].status[p] == HdrStatus::single) && hdr[k].rate[p] > 0;
      if (!valid) continue;
      for (std::size_t k = 0; k < K; ++k) {
        const double r = hdr[k].rate[p];
        sum[Eigen::Index(k)] += hdr_rate_variance(r, times[k], cap.bit_depth, noise, o) / (r * r);
      }
      ++pixels;
    }
  }
  if (pixels == 0)
    throw InputError(dir.string() + ": no scene pixel is read in every filter; the readings' noise is unknown");
  return (sum / double(pixels)).cwiseSqrt();
}

namespace {

void add_target_reports(Calibration& c, const Capture& cap, const Eigen::MatrixXd& measured,
                        const Eigen::MatrixXd& reflectance, const std::vector<Eigen::Index>& fit_rows);
void calibrate_lctf(Calibration& c, const Capture& cap, const fs::path& dir, const Tabulated& light,
                    const PipelineOptions& o, const Eigen::MatrixXd& measured, const Eigen::MatrixXd& reflectance,
                    const std::vector<Eigen::Index>& fit_rows);
void calibrate_geometry(Calibration& c, const Capture& cap, const fs::path& dir);

}  // namespace

Calibration calibrate_capture(const Capture& cap, const fs::path& dir, const PipelineOptions& o) {
  Calibration c;
  const std::size_t B = cap.channels();
  // Spatial response from the flat fields' HDR rates.
  std::vector<GreyImage> flats;
  for (std::size_t b = 0; b < B; ++b) {
    const HdrImage h = merge_series(cap, dir, ImageKind::flat, -1, -1, int(b), o.hdr);
    flats.push_back({cap.width, cap.height, h.rate});
  }
  c.spatial = spatial_response(flats);

  // Targets: the mean flat-corrected rate over the central tenth of the image.
  const std::size_t T = cap.targets.size();
  if (T == 0) throw InputError((dir / "manifest.json").string() + ": no diffuse targets for spectral calibration");
  Eigen::MatrixXd measured(static_cast<Eigen::Index>(T), static_cast<Eigen::Index>(B));
  Eigen::MatrixXd reflectance(static_cast<Eigen::Index>(T), static_cast<Eigen::Index>(cap.bands.size()));
  const int u0 = int(cap.width * 0.45), u1 = int(cap.width * 0.55) + 1, v0 = int(cap.height * 0.45),
            v1 = int(cap.height * 0.55) + 1;
  for (std::size_t t = 0; t < T; ++t)
    for (std::size_t b = 0; b < B; ++b) {
      const HdrImage h = merge_series(cap, dir, ImageKind::target, -1, int(t), int(b), o.hdr);
      double sum = 0;
      int n = 0;
      for (int v = v0; v < v1; ++v)
        for (int u = u0; u < u1; ++u) {
          const std::size_t p = std::size_t(v) * std::size_t(cap.width) + std::size_t(u);
          if (h.status[p] == HdrStatus::saturated) continue;
          sum += h.rate[p] / c.spatial.value[p];
          ++n;
        }
      if (n == 0)
        throw InputError(dir.string() + ": target '" + cap.targets[t].name + "' is saturated " +
                         (cap.filters ? "through filter '" + cap.filters->names[b] + "'"
                                      : "at " + std::to_string(int(cap.bands[b])) + " nm"));
      measured(Eigen::Index(t), Eigen::Index(b)) = sum / n;
    }
  for (std::size_t t = 0; t < T; ++t)
    for (std::size_t b = 0; b < cap.bands.size(); ++b)
      reflectance(Eigen::Index(t), Eigen::Index(b)) = cap.targets[t].reflectance[b];
  std::vector<Eigen::Index> fit_rows;
  for (std::size_t t = 0; t < T; ++t)
    if (std::find(o.fit_targets.begin(), o.fit_targets.end(), cap.targets[t].name) != o.fit_targets.end())
      fit_rows.push_back(Eigen::Index(t));
  if (fit_rows.empty()) throw UsageError("spectral calibration: none of the fitting targets is in the capture");
  const Eigen::MatrixXd fit_h = measured(fit_rows, Eigen::all), fit_r = reflectance(fit_rows, Eigen::all);
  const Tabulated light{cap.light_spectrum_nm, cap.light_spectrum};
  if (cap.filters) {
    c.spectral = calibrate_filters(cap, dir, light, o, fit_h, fit_r);
    add_target_reports(c, cap, measured, reflectance, fit_rows);
  } else {
    calibrate_lctf(c, cap, dir, light, o, measured, reflectance, fit_rows);
  }
  calibrate_geometry(c, cap, dir);
  return c;
}

namespace {

SpectralCalibration calibrate_filters(const Capture& cap, const fs::path& dir, const Tabulated& light,
                                      const PipelineOptions& o, const Eigen::MatrixXd& fit_h,
                                      const Eigen::MatrixXd& fit_r) {
  const std::vector<Eigen::MatrixXd> system = filter_system(*cap.filters, cap.bands, light, o.filter_terms);
  const Eigen::MatrixXd a = fit_filter_response(system, fit_h, fit_r);
  SpectralCalibration s;
  s.model = SpectralModel::filters;
  s.bands = cap.bands;
  Eigen::MatrixXd sys = Eigen::MatrixXd::Zero(system[0].rows(), system[0].cols());
  for (Eigen::Index k = 0; k < sys.rows(); ++k)
    for (std::size_t d = 0; d < system.size(); ++d) sys.row(k) += a(k, Eigen::Index(d)) * system[d].row(k);
  s.scale = Eigen::Map<const Eigen::VectorXd>(Eigen::MatrixXd(a.transpose()).data(), a.size());
  if (o.filter_prior.size()) {
    s.noise = Eigen::VectorXd::Constant(sys.rows(), o.filter_noise);
    if (o.filter_noise_from_capture) {
      const Eigen::VectorXd rel = filter_reading_noise(cap, dir, o.sensor, o.hdr, o.filter_noise_lights);
      std::vector<double> sorted(rel.data(), rel.data() + rel.size());
      std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
      s.noise *= 1.0 / sorted[sorted.size() / 2];
      s.noise = s.noise.cwiseProduct(rel);
    }
    const Eigen::VectorXd sigma = s.noise.cwiseProduct(sys.rowwise().sum().cwiseAbs());
    s.recovery = filter_wiener_recovery(sys, o.filter_prior, sigma);
    s.posterior = filter_wiener_posterior(sys, o.filter_prior, sigma);
  } else {
    s.recovery = filter_recovery(sys, o.filter_basis, o.filter_ridge);
    s.posterior = filter_ridge_posterior(sys, o.filter_basis, o.filter_ridge);
  }
  return s;
}

void add_target_reports(Calibration& c, const Capture& cap, const Eigen::MatrixXd& measured,
                        const Eigen::MatrixXd& reflectance, const std::vector<Eigen::Index>& fit_rows) {
  for (std::size_t t = 0; t < cap.targets.size(); ++t) {
    TargetReport r;
    r.name = cap.targets[t].name;
    r.held_out = std::find(fit_rows.begin(), fit_rows.end(), Eigen::Index(t)) == fit_rows.end();
    r.truth = reflectance.row(Eigen::Index(t)).transpose();
    r.filters = recover_spectrum(c.spectral, measured.row(Eigen::Index(t)).transpose());
    r.rms_filters = spectral_rms(r.filters, r.truth);
    c.targets.push_back(std::move(r));
  }
}

// The LCTF's delta and factored models fitted on the targets, the chosen one kept, every target reported under both.
void calibrate_lctf(Calibration& c, const Capture& cap, const fs::path& dir, const Tabulated& light,
                    const PipelineOptions& o, const Eigen::MatrixXd& measured, const Eigen::MatrixXd& reflectance,
                    const std::vector<Eigen::Index>& fit_rows) {
  const std::size_t B = cap.bands.size(), T = cap.targets.size();
  const Eigen::MatrixXd fit_h = measured(fit_rows, Eigen::all), fit_r = reflectance(fit_rows, Eigen::all);
  const SpectralCalibration delta = fit_delta(cap.bands, light, fit_h, fit_r);
  std::optional<SpectralCalibration> factored;
  if (!cap.lctf_nm.empty()) {
    std::vector<Tabulated> trans;
    for (std::size_t b = 0; b < B; ++b) trans.push_back({cap.lctf_nm[b], cap.lctf_value[b]});
    factored = fit_factored(cap.bands, light, trans, fit_h, fit_r);
  }
  if (o.spectral == SpectralModel::factored && !factored)
    throw InputError((dir / "manifest.json").string() + ": the factored model needs \"lctf_transmission\" data");
  c.spectral = o.spectral == SpectralModel::factored ? *factored : delta;
  for (std::size_t t = 0; t < T; ++t) {
    TargetReport r;
    r.name = cap.targets[t].name;
    r.held_out = std::find(fit_rows.begin(), fit_rows.end(), Eigen::Index(t)) == fit_rows.end();
    r.truth = reflectance.row(Eigen::Index(t)).transpose();
    const Eigen::VectorXd h = measured.row(Eigen::Index(t)).transpose();
    r.delta = delta.recovery * h;
    r.rms_delta = spectral_rms(r.delta, r.truth);
    if (factored) {
      r.factored = factored->recovery * h;
      r.rms_factored = spectral_rms(r.factored, r.truth);
    }
    c.targets.push_back(std::move(r));
  }
}

void calibrate_geometry(Calibration& c, const Capture& cap, const fs::path& dir) {
  // Geometry: circle (eq 5.1), sphere (eq 5.2).
  const GreyImage sil = load_grey(cap, dir, only_image(cap, ImageKind::silhouette, -1, dir).file);
  try {
    c.circle = detect_circle(sil);
  } catch (const InputError& e) {
    throw InputError((dir / only_image(cap, ImageKind::silhouette, -1, dir).file).string() + ": " + e.what());
  }
  const Pinhole camera{cap.focal_px, cap.cx, cap.cy};
  c.sphere = fit_sphere(c.circle, camera, cap.sphere_radius_m > 0 ? cap.sphere_radius_m : 1.0, cap.width, cap.height);
  c.light_distance = cap.light_distance_m;

  // Lights: each mirror highlight (eq 5.3), then the arc through them.
  const std::size_t L = cap.light_angles_deg.size();
  std::vector<Eigen::Vector3d> measured_dirs(L, Eigen::Vector3d::UnitZ());
  c.light_confidence.assign(L, 0.0);
  for (std::size_t l = 0; l < L; ++l) {
    const CaptureImage* im = nullptr;
    for (const auto& x : cap.images)
      if (x.kind == ImageKind::mirror && x.light == int(l)) im = &x;
    if (!im) continue;
    try {
      double w = 0;
      measured_dirs[l] = light_direction(load_grey(cap, dir, im->file), camera, c.sphere, c.light_distance, &w);
      c.light_confidence[l] = w;
    } catch (const InputError&) {
      // No highlight (the light behind the sphere): the arc places it.
    }
  }
  std::vector<double> weights(L);
  for (std::size_t l = 0; l < L; ++l) weights[l] = c.light_confidence[l] * c.light_confidence[l];
  if (std::count_if(weights.begin(), weights.end(), [](double w) { return w > 0; }) < 2)
    throw InputError(dir.string() +
                     ": fewer than two mirror images show the light's highlight; the lights cannot be placed");
  c.light_dirs = fit_light_arc(measured_dirs, weights, cap.light_angles_deg);
}

// Pixels wholly on the sphere (4 x 4 samples inside), with their point, normal and view.
std::vector<ScanPixel> sphere_pixels(const Capture& cap, const Sphere& sphere) {
  const Pinhole camera{cap.focal_px, cap.cx, cap.cy};
  std::vector<ScanPixel> pixels;
  for (int v = 0; v < cap.height; ++v)
    for (int u = 0; u < cap.width; ++u) {
      bool all = true;
      double t;
      for (int k = 0; k < 16 && all; ++k) all = sphere.hit(camera.ray(u + (k % 4 + 0.5) / 4, v + (k / 4 + 0.5) / 4), t);
      if (!all) continue;
      const Eigen::Vector3d d = camera.ray(u + 0.5, v + 0.5);
      sphere.hit(d, t);
      const Eigen::Vector3d x = t * d;
      pixels.push_back({u, v, x, (x - sphere.centre).normalized(), -d});
    }
  return pixels;
}

}  // namespace

Reject pixel_readings(const std::vector<HdrImage>& hdr, std::size_t p, const GreyImage& spatial,
                      const PipelineOptions& o, Eigen::VectorXd& h) {
  h.resize(Eigen::Index(hdr.size()));
  Reject why = Reject::count;
  bool lit = false;
  for (std::size_t b = 0; b < hdr.size(); ++b) {
    const HdrStatus s = hdr[b].status[p];
    double rate = hdr[b].rate[p];
    if (why == Reject::count && s == HdrStatus::saturated) why = Reject::saturated;
    if (why == Reject::count && s == HdrStatus::nonlinear) why = Reject::nonlinear;
    if (s == HdrStatus::low_signal) {
      if (why == Reject::count && !o.keep_dark_channels) why = Reject::low_signal;
      rate = std::max(0.0, rate - o.sensor.dark_dn / hdr[b].longest_time);
    } else {
      lit = true;
    }
    h[Eigen::Index(b)] = rate / spatial.value[p];
  }
  return why == Reject::count && !lit ? Reject::low_signal : why;
}

Eigen::VectorXd recover_spectrum(const SpectralCalibration& s, const Eigen::VectorXd& h) {
  Eigen::VectorXd f = s.recovery * h;
  if (s.posterior.size()) nonnegative_spectrum(s.posterior, f);
  return f;
}

ExtractResult extract_samples(const Capture& cap, const fs::path& dir, const Calibration& c, const PipelineOptions& o,
                              store::StoreWriter& out, const std::string& name) {
  const std::size_t B = cap.channels(), W = std::size_t(cap.width), H = std::size_t(cap.height);
  if (c.spectral.recovery.cols() != Eigen::Index(B) || c.spectral.recovery.rows() != Eigen::Index(cap.bands.size()))
    throw InputError(dir.string() + ": the calibration recovers " + std::to_string(c.spectral.recovery.rows()) +
                     " bands from " + std::to_string(c.spectral.recovery.cols()) + " channels; the capture has " +
                     std::to_string(cap.bands.size()) + " bands and " + std::to_string(B) + " channels");
  const std::vector<ScanPixel> pixels = sphere_pixels(cap, c.sphere);
  ExtractResult r;
  r.sphere_pixels = pixels.size();
  store::Provenance prov;
  prov.source_file = dir.string();
  prov.importer = "acquire";
  out.create_samples(name, WavelengthGrid(cap.bands), "1/sr", prov, true);
  const std::size_t L = cap.light_angles_deg.size();
  Progress progress("samples", L);
  std::vector<double> angles;
  std::vector<float> values, variance;
  std::vector<std::uint8_t> saturated(W * H);
  for (std::size_t l = 0; l < L; ++l) {
    check_interrupt();
    const std::vector<HdrImage> hdr = merge_light(cap, dir, int(l), o.hdr);
    const SampleNoise noise(cap, dir, int(l), c.spectral, o.sensor, o.hdr);
    std::fill(saturated.begin(), saturated.end(), 0);
    for (std::size_t b = 0; b < B; ++b) {
      std::size_t on_sphere = 0;
      for (const ScanPixel& px : pixels) {
        const std::size_t p = std::size_t(px.y) * W + std::size_t(px.x);
        if (hdr[b].status[p] == HdrStatus::saturated) saturated[p] = 1, ++on_sphere;
      }
      if (!pixels.empty() && on_sphere == pixels.size())
        throw InputError(dir.string() + ": light " + std::to_string(l) +
                         (cap.filters ? " through filter '" + cap.filters->names[b] + "'"
                                      : " at " + std::to_string(int(cap.bands[b])) + " nm") +
                         " is saturated on the whole sphere even at the shortest exposure; capture shorter exposures");
    }
    for (std::size_t p = 0; p < W * H; ++p)
      for (std::size_t b = 0; b < B && !saturated[p]; ++b)
        if (hdr[b].status[p] == HdrStatus::saturated) saturated[p] = 1;
    const Eigen::Vector3d light = c.light_distance > 0
                                      ? Eigen::Vector3d(c.sphere.centre + c.light_distance * c.light_dirs[l])
                                      : Eigen::Vector3d(c.sphere.centre + 1e6 * c.light_dirs[l]);
    angles.clear();
    values.clear();
    variance.clear();
    Eigen::VectorXd h;
    for (const ScanPixel& px : pixels) {
      const std::size_t p = std::size_t(px.y) * W + std::size_t(px.x);
      brdf::StdAngles a;
      if (!scan_angles(px, light, a)) {
        ++r.rejected[std::size_t(Reject::shadowed)];
        continue;
      }
      if (saturated[p]) {
        ++r.rejected[std::size_t(Reject::saturated)];
        continue;
      }
      bool bloom = false;
      for (int dv = -o.bloom_px; dv <= o.bloom_px && !bloom; ++dv)
        for (int du = -o.bloom_px; du <= o.bloom_px && !bloom; ++du) {
          const int u = px.x + du, v = px.y + dv;
          bloom = u >= 0 && v >= 0 && u < int(W) && v < int(H) && saturated[std::size_t(v) * W + std::size_t(u)];
        }
      if (bloom) {
        ++r.rejected[std::size_t(Reject::bloom)];
        continue;
      }
      const Reject why = pixel_readings(hdr, p, c.spatial, o, h);
      if (why != Reject::count) {
        ++r.rejected[std::size_t(why)];
        continue;
      }
      // Irradiance: pi cos(theta_i) (D / d)^2 relative to a surface facing the light at the arc's radius, the
      // targets' geometry (a distant light: pi cos(theta_i)).
      const double d = (light - px.point).norm();
      const double g = pi * std::cos(a.theta_i) * (c.light_distance > 0 ? std::pow(c.light_distance / d, 2) : 1.0);
      const Eigen::VectorXd f = recover_spectrum(c.spectral, h / g);
      const Eigen::VectorXd v = noise.variance(hdr, p, c.spatial.value[p] * g);
      angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
      for (Eigen::Index b = 0; b < f.size(); ++b) values.push_back(float(f[b])), variance.push_back(float(v[b]));
      ++r.samples;
    }
    if (!angles.empty()) out.append_samples(name, angles, values, variance);
    progress.advance();
  }
  return r;
}

void write_calibration(store::StoreWriter& out, const std::string& name, const Calibration& c) {
  store::validate_name(name, "calibration");
  store::Record r;
  Eigen::MatrixXd s(c.spatial.height, c.spatial.width);
  for (int v = 0; v < c.spatial.height; ++v)
    for (int u = 0; u < c.spatial.width; ++u) s(v, u) = c.spatial.at(u, v);
  Eigen::MatrixXd lights(Eigen::Index(c.light_dirs.size()), 3);
  for (std::size_t l = 0; l < c.light_dirs.size(); ++l) lights.row(Eigen::Index(l)) = c.light_dirs[l].transpose();
  r.matrices = {{"spatial_response", s}, {"spectral_recovery", c.spectral.recovery}, {"light_dirs", lights}};
  if (c.spectral.posterior.size()) r.matrices.emplace_back("spectral_posterior", c.spectral.posterior);
  r.vectors = {{"spectral_scale",
                std::vector<double>(c.spectral.scale.data(), c.spectral.scale.data() + c.spectral.scale.size())},
               {"bands_nm", c.spectral.bands},
               {"circle_px", {c.circle.cx, c.circle.cy, c.circle.r}},
               {"sphere_m", {c.sphere.centre.x(), c.sphere.centre.y(), c.sphere.centre.z(), c.sphere.radius}},
               {"light_confidence", c.light_confidence},
               {"light_distance_m", {c.light_distance}}};
  if (c.spectral.noise.size())
    r.vectors.emplace_back("filter_noise", std::vector<double>(c.spectral.noise.data(),
                                                               c.spectral.noise.data() + c.spectral.noise.size()));
  r.texts = {{"spectral_model", c.spectral.model == SpectralModel::delta      ? "delta"
                                : c.spectral.model == SpectralModel::factored ? "factored"
                                                                              : "filters"}};
  r.provenance.importer = "acquire calibrate";
  out.add_record("acquire", name, r);
}

Calibration read_calibration(const store::Store& in, const std::string& name) {
  const std::vector<std::string> names = in.objects("acquire");
  if (name.empty() || name.find('/') != std::string::npos || std::find(names.begin(), names.end(), name) == names.end())
    throw InputError(in.label() + ": no calibration '" + name + "' (run specula acquire calibrate first)");
  const store::Record r = in.read_record("acquire", name);
  Calibration c;
  const Eigen::MatrixXd& s = r.matrix("spatial_response");
  c.spatial = {int(s.cols()), int(s.rows()), std::vector<float>(std::size_t(s.size()))};
  for (Eigen::Index v = 0; v < s.rows(); ++v)
    for (Eigen::Index u = 0; u < s.cols(); ++u) c.spatial.value[std::size_t(v * s.cols() + u)] = float(s(v, u));
  c.spectral.recovery = r.matrix("spectral_recovery");
  // Calibrations written before the non-negative reconstruction have no posterior: their recovery stays linear.
  for (const auto& [key, m] : r.matrices)
    if (key == "spectral_posterior") c.spectral.posterior = m;
  for (const auto& [key, v] : r.vectors)
    if (key == "filter_noise") c.spectral.noise = Eigen::Map<const Eigen::VectorXd>(v.data(), Eigen::Index(v.size()));
  const std::vector<double>& scale = r.vector("spectral_scale");
  c.spectral.scale = Eigen::Map<const Eigen::VectorXd>(scale.data(), Eigen::Index(scale.size()));
  c.spectral.bands = r.vector("bands_nm");
  const std::string model = r.text("spectral_model");
  c.spectral.model = model == "factored"  ? SpectralModel::factored
                     : model == "filters" ? SpectralModel::filters
                                          : SpectralModel::delta;
  const std::vector<double>& circle = r.vector("circle_px");
  const std::vector<double>& sphere = r.vector("sphere_m");
  if (circle.size() != 3 || sphere.size() != 4 || c.spectral.recovery.rows() != Eigen::Index(c.spectral.bands.size()) ||
      (c.spectral.posterior.size() && (c.spectral.posterior.rows() != c.spectral.recovery.rows() ||
                                       c.spectral.posterior.cols() != c.spectral.recovery.rows())))
    throw InputError(r.label + ": malformed calibration");
  c.circle = {circle[0], circle[1], circle[2]};
  c.sphere = {Eigen::Vector3d(sphere[0], sphere[1], sphere[2]), sphere[3]};
  const Eigen::MatrixXd& lights = r.matrix("light_dirs");
  for (Eigen::Index l = 0; l < lights.rows(); ++l) c.light_dirs.push_back(lights.row(l).transpose());
  c.light_confidence = r.vector("light_confidence");
  const std::vector<double>& distance = r.vector("light_distance_m");
  if (distance.size() != 1) throw InputError(r.label + ": malformed light_distance_m");
  c.light_distance = distance[0];
  return c;
}

}  // namespace specula::acquire
