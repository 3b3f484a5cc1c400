// specula acquire STEP: the pipeline from a capture directory (docs/capture-format.md) to scattered BRDF samples,
// one subcommand per step, each recording its result in a store: hdr (HDR images per light), calibrate (spatial,
// spectral, sphere and lights under /acquire/NAME), samples (scattered samples from a stored calibration), run
// (calibrate and samples in one go). --plots draws the incidence-plane plots (figures 5.5-5.7) and the spectral
// calibration comparison (figures 4.6-4.9).
#include <fmt/format.h>

#include <array>
#include <chrono>
#include <filesystem>
#include <numbers>
#include <optional>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/gnuplot.h"
#include "specula/acquire/capture.h"
#include "specula/acquire/filter_design.h"
#include "specula/acquire/hdr.h"
#include "specula/acquire/holdout.h"
#include "specula/acquire/incidence.h"
#include "specula/acquire/pipeline.h"
#include "specula/acquire/plane_plot.h"
#include "specula/acquire/scan.h"
#include "specula/acquire/simulate.h"
#include "specula/acquire/store_samples.h"
#include "specula/acquire/truth.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_mapping.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/brdf_resample.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct AcquireHdrOptions {
  std::string capture;
  std::string output;
  double low = 15.0 / 255, high = 240.0 / 255, min_pearson = 0.99;
  bool replace = false;
  bool json = false;
};

// Merges every light's exposure series into one image per light position, "hdr-L<index>".
void run_acquire_hdr(const AcquireHdrOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const acquire::Capture cap = acquire::read_manifest(o.capture);
  store::StoreWriter writer(o.output, {.replace = o.replace, .command_line = command_line()});
  const acquire::HdrSummary sum = acquire::write_hdr_images(cap, o.capture, {o.low, o.high, o.min_pearson}, writer);
  writer.commit();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  auto name = [](std::size_t s) { return acquire::status_name(acquire::HdrStatus(s)); };
  if (o.json) {
    Json by;
    for (std::size_t s = 0; s < sum.status.size(); ++s) by[name(s)] = sum.status[s];
    Json j;
    j["lights"] = sum.lights;
    j["bands"] = sum.bands;
    j["pixels"] = sum.pixels;
    j["valid_pixels"] = sum.valid_pixels;
    j["status"] = std::move(by);
    j["seconds"] = seconds;
    print_json(j);
    return;
  }
  fmt::print("merged {} light positions x {} bands into {} ({} of {} pixels valid in every band) in {:.1f} s\n",
             sum.lights, sum.bands, o.output, sum.valid_pixels, sum.pixels, seconds);
  for (std::size_t s = 0; s < sum.status.size(); ++s) fmt::print("  {:<11} {}\n", name(s), sum.status[s]);
}

struct AcquireOptions {
  std::string capture;
  std::string output;       // STORE.h5[:NAME]
  std::string calibration;  // samples: the stored calibration's name (default: NAME)
  std::string spectral = "delta";
  std::string plots;
  std::vector<double> plot_theta = {30, 45, 60};
  double plot_band_nm = 0;
  std::size_t grid_k = 32;  // the suite check's resampling, as `specula resample`'s -k and --max-gap
  double grid_max_gap_deg = brdf::kDefaultMaxGapDegrees;
  bool suite = true;
  std::string basis;  // filter captures: STORE.h5:BASIS
  double ridge = 1e-3;
  int filter_terms = 2;
  std::string filter_solve = "wiener";
  double filter_noise = 0.002;
  bool equal_filter_noise = false;
  double read_noise_dn = acquire::SensorNoise{}.read_noise_dn;
  double electrons_per_dn = acquire::SensorNoise{}.electrons_per_dn;
  double bias_dn = acquire::SensorNoise{}.dark_dn;
  bool reject_dark = false;
  std::vector<std::string> fit_targets;
  bool replace = false;
  bool json = false;
};

std::pair<std::string, std::string> split_output(const std::string& spec, const std::string& fallback) {
  if (const auto s = store::parse_object_spec(spec); s && s->file.string().size() > 1)
    return {s->file.string(), s->name};
  return {spec, fallback};
}

// Figures 4.6-4.9: each target's known reflectance against the delta and factored recoveries, into `png`.
void plot_targets(const std::filesystem::path& gnuplot, const std::filesystem::path& png,
                  const std::vector<acquire::TargetReport>& targets, const std::vector<double>& bands) {
  std::string script;
  for (std::size_t t = 0; t < targets.size(); ++t)
    script += fmt::format("$T{} << EOD\n{}EOD\n", t, acquire::target_table(targets[t], bands));
  const std::size_t n = targets.size(), cols = std::min<std::size_t>(n, n > 9 ? 6 : 3), rows = (n + cols - 1) / cols;
  script += fmt::format(
      "set multiplot layout {},{}\nset grid\nset key bottom right\nset xlabel 'wavelength (nm)'\nset yrange [0:1.1]\n",
      rows, cols);
  for (std::size_t t = 0; t < n; ++t) {
    const auto& r = targets[t];
    script += "set title " +
              gnuplot_quote(
                  fmt::format("{} ({}): RMS {} {:.4f}{}", r.name, r.held_out ? "held out" : "fitted",
                              r.filters.size() ? "filters" : "delta", r.filters.size() ? r.rms_filters : r.rms_delta,
                              r.rms_factored >= 0 ? fmt::format(", factored {:.4f}", r.rms_factored) : std::string())) +
              " noenhanced\n";
    script += fmt::format(
        "plot $T{0} using 1:2 with lines lw 2 lc rgb '#222222' title 'known', "
        "$T{0} using 1:3 with linespoints pt 7 ps 0.5 lc rgb '#d04020' title '{1}', "
        "$T{0} using 1:4 with linespoints pt 5 ps 0.5 lc rgb '#2060c0' title 'factored'\n",
        t, r.filters.size() ? "filters" : "delta");
  }
  script += "unset multiplot\n";
  plot_png(gnuplot, png, gnuplot_png_terminal(int(cols) * 420, int(rows) * 320), script);
}

// The held-out patches as target reports (held out, recovered by the capture's model) for plot_targets.
std::vector<acquire::TargetReport> holdout_as_targets(const std::vector<acquire::HoldoutReport>& holdout,
                                                      const acquire::Calibration& c) {
  std::vector<acquire::TargetReport> out;
  for (const auto& h : holdout) {
    acquire::TargetReport r{h.name, true, h.truth};
    const Eigen::VectorXd recovered = h.pixels ? h.recovered : Eigen::VectorXd::Constant(h.truth.size(), NAN);
    if (c.spectral.model == acquire::SpectralModel::filters)
      r.filters = recovered, r.rms_filters = h.rms;
    else
      r.delta = recovered, r.rms_delta = h.rms;
    out.push_back(std::move(r));
  }
  return out;
}

// Mean and largest eq 4.8 over the held-out patches that had usable pixels (-1 when none had).
std::pair<double, double> holdout_summary(const std::vector<acquire::HoldoutReport>& holdout) {
  double sum = 0, worst = -1;
  std::size_t n = 0;
  for (const auto& h : holdout)
    if (h.rms >= 0) sum += h.rms, worst = std::max(worst, h.rms), ++n;
  return {n ? sum / double(n) : -1.0, worst};
}

Json holdout_json(const std::vector<acquire::HoldoutReport>& holdout) {
  Json patches = Json::array();
  for (const auto& h : holdout)
    patches.push_back({{"name", h.name},
                       {"rms", h.rms},
                       {"recovered", std::vector<double>(h.recovered.data(), h.recovered.data() + h.recovered.size())},
                       {"pixel_rms", h.pixel_rms},
                       {"pixels", h.pixels},
                       {"rejected", h.rejected}});
  const auto [mean, worst] = holdout_summary(holdout);
  return {{"patches", std::move(patches)}, {"rms_mean", mean}, {"rms_max", worst}};
}

void print_holdout(const std::vector<acquire::HoldoutReport>& holdout) {
  fmt::print(
      "held-out patches (never used by calibration), recovered from their images:\n"
      "  patch                     RMS (eq 4.8)  per-pixel RMS  pixels\n");
  for (const auto& h : holdout)
    fmt::print("  {:<24}  {}  {}  {} ({} rejected)\n", h.name,
               h.rms >= 0 ? fmt::format("{:12.5f}", h.rms) : fmt::format("{:>12}", "-"),
               h.pixel_rms >= 0 ? fmt::format("{:13.5f}", h.pixel_rms) : fmt::format("{:>13}", "-"), h.pixels,
               h.rejected);
  const auto [mean, worst] = holdout_summary(holdout);
  fmt::print("  mean {:.5f}, largest {:.5f}\n", mean, worst);
}

// A simulated capture's material on `wavelengths` (a named material or the grid it was simulated from), or null.
std::unique_ptr<brdf::SpectralModel> truth_model(const acquire::Capture& cap, const WavelengthGrid& wavelengths) {
  if (!cap.truth || cap.truth->material.empty()) return nullptr;
  if (brdf::material_catalogue().count(cap.truth->material))
    return brdf::make_material(cap.truth->material, wavelengths);
  try {
    return acquire::grid_material(std::make_shared<const store::Grid>(load_grid(cap.truth->material, "acquire")),
                                  wavelengths);
  } catch (const std::exception&) {
    return nullptr;  // the simulated grid is no longer where the manifest says
  }
}

// The samples resampled onto the MERL grid as `specula resample` does, against the simulated material at every cell,
// under the lighting suite (docs/brdf.md): what a renderer would see of the acquisition, holes black.
struct SuiteCheck {
  codec::SuiteDiff diff;
  std::string worst;
  Json json;
};
SuiteCheck suite_against_truth(const store::Store& s, const std::string& name, const brdf::SpectralModel& model,
                               const AcquireOptions& o) {
  const store::SamplesInfo info = s.samples_info(name);
  store::Grid truth, grid;
  truth.wavelengths = grid.wavelengths = info.wavelengths;
  truth.units = grid.units = info.units;
  truth.brdf.resize(info.bands * brdf::kMerlCells);
  brdf::evaluate_grid(model, truth.brdf);
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  const brdf::ResampleOptions ro{.k = o.grid_k, .max_gap = o.grid_max_gap_deg * std::numbers::pi / 180};
  brdf::check_options(ro);
  brdf::resample_grid(acquire::StoreSamples(s, name), ro, grid.brdf);
  const codec::LightingSuite suite(info.wavelengths);
  SuiteCheck c{codec::suite_diff(truth, grid, suite), "", Json()};
  c.worst = suite.conditions()[c.diff.worst].name;
  c.json = Json::parse(codec::suite_json(c.diff, suite));
  c.json["grid_k"] = o.grid_k;
  c.json["grid_max_gap_deg"] = o.grid_max_gap_deg;
  return c;
}

// Figures 5.5-5.7: cube root of the samples within 2 degrees of the incidence plane at theta_i, at one band; with
// a simulated capture's material, its model along the plane too.
void plot_incidence(const std::filesystem::path& gnuplot, const std::filesystem::path& dir, const store::Store& s,
                    const std::string& name, const acquire::Capture& cap, const AcquireOptions& o) {
  using std::numbers::pi;
  const store::SamplesInfo info = s.samples_info(name);
  const std::size_t band = o.plot_band_nm > 0 ? info.wavelengths.nearest(o.plot_band_nm) : info.bands / 2;
  const auto model = truth_model(cap, info.wavelengths);
  const double eps = 2 * pi / 180;
  std::vector<double> theta_i;
  for (const double t : o.plot_theta) theta_i.push_back(t * pi / 180);
  const std::vector<acquire::PlanePoints> planes = acquire::incidence_plane_points(s, name, theta_i, eps, band);
  for (std::size_t k = 0; k < o.plot_theta.size(); ++k) {
    std::string script = "$S << EOD\n" + acquire::plane_points_table(planes[k].points) + "EOD\n";
    if (model) script += "$M << EOD\n" + acquire::model_plane_table(*model, theta_i[k], band) + "EOD\n";
    script +=
        "set grid\nset key top left\nset xrange [-90:90]\nset xlabel 'theta_o (degrees; negative: the light''s "
        "side)'\n";
    script += "set ylabel 'cube root of the BRDF (1/sr)'\n";
    script += "set title " +
              gnuplot_quote(fmt::format("{}: incidence plane at theta_i = {} deg, {} nm, samples within 2 deg", name,
                                        o.plot_theta[k], info.wavelengths[band])) +
              " noenhanced\n";
    script += "plot $S using 1:2 with points pt 7 ps 0.5 lc rgb '#d04020' title 'samples'";
    if (model)
      script += ", $M using 1:2 with lines lw 2 lc rgb '#2060c0' title " +
                gnuplot_quote("model (" + cap.truth->material + ")") + " noenhanced";
    script += "\n";
    plot_png(gnuplot, dir / fmt::format("incidence-theta{:g}.png", o.plot_theta[k]), gnuplot_png_terminal(900, 560),
             script);
  }
}

void print_calibration(const acquire::Capture& cap, const acquire::Calibration& c) {
  fmt::print(
      "circle: centre ({:.2f}, {:.2f}) px, radius {:.2f} px; sphere: centre ({:.4f}, {:.4f}, {:.4f}) m, radius {:.4f} "
      "m\n",
      c.circle.cx, c.circle.cy, c.circle.r, c.sphere.centre.x(), c.sphere.centre.y(), c.sphere.centre.z(),
      c.sphere.radius);
  std::size_t seen = 0;
  for (const double w : c.light_confidence) seen += w > 0;
  fmt::print("lights: {} on the arc, {} placed from mirror highlights\n", c.light_dirs.size(), seen);
  const bool filters = c.spectral.model == acquire::SpectralModel::filters;
  fmt::print("spectral model: {} (fitted on targets",
             filters ? fmt::format("{} broadband filters", c.spectral.recovery.cols())
             : c.spectral.model == acquire::SpectralModel::delta ? "delta"
                                                                 : "factored");
  for (const auto& t : c.targets)
    if (!t.held_out) fmt::print(" {}", t.name);
  if (filters) {
    fmt::print(")\n  target      RMS filters (eq 4.8)\n");
    for (const auto& t : c.targets)
      fmt::print("  {:<10}  {:.5f}{}\n", t.name, t.rms_filters, t.held_out ? "" : "   (fitted)");
    if (c.spectral.noise.size())
      fmt::print("  reading noise per filter (relative to its white reading): {:.4f}\n",
                 fmt::join(c.spectral.noise, " "));
    return;
  }
  fmt::print(")\n  target      RMS delta   RMS factored (eq 4.8)\n");
  for (const auto& t : c.targets)
    fmt::print("  {:<10}  {:.5f}     {}{}\n", t.name, t.rms_delta,
               t.rms_factored >= 0 ? fmt::format("{:.5f}", t.rms_factored) : "-", t.held_out ? "" : "   (fitted)");
  (void)cap;
}

// The calibration's circle, sphere and targets and, when the manifest has the truth, the mean and largest angle between
// the calibrated and the true light directions, added to `j`.
void add_calibration_json(Json& j, const acquire::Capture& cap, const acquire::Calibration& c) {
  Json targets = Json::array();
  for (const auto& t : c.targets)
    targets.push_back(t.filters.size()
                          ? Json{{"name", t.name}, {"held_out", t.held_out}, {"rms_filters", t.rms_filters}}
                          : Json{{"name", t.name},
                                 {"held_out", t.held_out},
                                 {"rms_delta", t.rms_delta},
                                 {"rms_factored", t.rms_factored}});
  const auto [mean, worst] = acquire::light_direction_error(cap, c);
  j["circle"] = {{"cx", c.circle.cx}, {"cy", c.circle.cy}, {"r", c.circle.r}};
  j["sphere"] = {{"centre", {c.sphere.centre.x(), c.sphere.centre.y(), c.sphere.centre.z()}},
                 {"radius", c.sphere.radius}};
  j["targets"] = std::move(targets);
  if (c.spectral.noise.size())
    j["filter_noise"] = std::vector<double>(c.spectral.noise.data(), c.spectral.noise.data() + c.spectral.noise.size());
  if (mean >= 0) {
    j["light_dir_error_deg"] = mean;
    j["light_dir_error_max_deg"] = worst;
  }
}

// The pipeline's settings from the options; a filter capture's basis (and its prior for the Wiener solve) read.
acquire::PipelineOptions pipeline_options(const AcquireOptions& o, const acquire::Capture& cap) {
  acquire::PipelineOptions po;
  po.spectral = acquire::parse_spectral_model(o.spectral);
  if (!o.fit_targets.empty()) po.fit_targets = o.fit_targets;
  po.filter_ridge = o.ridge;
  po.filter_terms = o.filter_terms;
  if (!o.basis.empty()) {
    const auto spec = store::parse_object_spec(o.basis);
    if (!spec) throw UsageError("acquire: --basis is STORE.h5:NAME");
    const store::Basis basis = store::Store::open(spec->file).read_basis(spec->name);
    po.filter_basis = acquire::capture_basis(basis, cap, o.basis);
    if (acquire::parse_filter_solve(o.filter_solve) == acquire::FilterSolve::wiener)
      po.filter_prior = acquire::capture_prior(basis, cap, o.basis);
    if (!(o.filter_noise >= 0 && o.filter_noise < 1)) throw UsageError("acquire: --filter-noise must be in [0, 1)");
    po.filter_noise = o.filter_noise;
    po.filter_noise_from_capture = !o.equal_filter_noise;
  }
  if (!(o.read_noise_dn >= 0) || !(o.electrons_per_dn > 0) || !(o.bias_dn >= 0))
    throw UsageError("acquire: --read-noise and --bias must be >= 0 and --electrons-per-dn positive");
  po.sensor.read_noise_dn = o.read_noise_dn;
  po.sensor.electrons_per_dn = o.electrons_per_dn;
  po.sensor.dark_dn = o.bias_dn;
  po.keep_dark_channels = !o.reject_dark;
  return po;
}

void run_acquire(const AcquireOptions& o, bool calibrate, bool extract) {
  const auto t0 = std::chrono::steady_clock::now();
  const acquire::Capture cap = acquire::read_manifest(o.capture);
  const acquire::PipelineOptions po = pipeline_options(o, cap);
  const auto [store_path, name] = split_output(o.output, "scan");
  store::validate_name(name, "samples");
  std::filesystem::path gnuplot;
  if (!o.plots.empty()) {
    gnuplot = find_gnuplot();
    if (gnuplot.empty()) throw UsageError("acquire: --plots draws with gnuplot; install it (Debian: gnuplot-nox)");
    for (const double t : o.plot_theta)
      if (!(t >= 0 && t < 90)) throw UsageError("acquire: --plot-theta values must be 0 to 90 degrees");
  }
  acquire::Calibration c;
  const auto t_cal = std::chrono::steady_clock::now();
  if (calibrate) {
    c = acquire::calibrate_capture(cap, o.capture, po);
  } else {
    c = acquire::read_calibration(store::Store::open(store_path), o.calibration.empty() ? name : o.calibration);
    if (c.spectral.bands != cap.bands)
      throw InputError(store_path + ": the stored calibration has " + std::to_string(c.spectral.bands.size()) +
                       " bands, the capture " + std::to_string(cap.bands.size()));
  }
  const std::vector<acquire::HoldoutReport> holdout =
      calibrate ? acquire::recover_holdout(cap, o.capture, c, po) : std::vector<acquire::HoldoutReport>{};
  const double calibrate_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_cal).count();
  const auto t_ext = std::chrono::steady_clock::now();
  acquire::ExtractResult r;
  {
    store::StoreWriter writer(store_path, {.replace = o.replace, .command_line = command_line()});
    if (calibrate) acquire::write_calibration(writer, name, c);
    if (extract) r = acquire::extract_samples(cap, o.capture, c, po, writer, name);
    writer.commit();
  }
  const double extract_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_ext).count();
  if (!o.plots.empty()) {
    std::filesystem::create_directories(o.plots);
    if (calibrate)
      plot_targets(gnuplot, std::filesystem::path(o.plots) / "spectral-calibration.png", c.targets, c.spectral.bands);
    if (!holdout.empty())
      plot_targets(gnuplot, std::filesystem::path(o.plots) / "holdout-patches.png", holdout_as_targets(holdout, c),
                   c.spectral.bands);
    if (extract) plot_incidence(gnuplot, o.plots, store::Store::open(store_path), name, cap, o);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::pair<double, double> truth{-1.0, -1.0};
  if (extract)
    if (const auto model = truth_model(cap, store::Store::open(store_path).samples_info(name).wavelengths))
      truth = acquire::sample_error(store::Store::open(store_path), name, *model);
  const auto [truth_err, truth_ratio] = truth;
  std::optional<SuiteCheck> suite;
  if (extract && o.suite)
    if (const store::Store s = store::Store::open(store_path);
        const auto model = truth_model(cap, s.samples_info(name).wavelengths))
      suite = suite_against_truth(s, name, *model, o);
  if (o.json) {
    Json rejected;
    for (std::size_t k = 0; k < r.rejected.size(); ++k) rejected[acquire::kRejectNames[k]] = r.rejected[k];
    Json j;
    j["samples"] = r.samples;
    j["sphere_pixels"] = r.sphere_pixels;
    j["rejected"] = std::move(rejected);
    add_calibration_json(j, cap, c);
    if (!holdout.empty()) j["holdout"] = holdout_json(holdout);
    if (truth_err >= 0) {
      j["truth_median_rel_error"] = truth_err;
      j["truth_median_ratio"] = truth_ratio;
    }
    if (suite) j["suite"] = suite->json;
    j["calibrate_seconds"] = calibrate_seconds;
    j["extract_seconds"] = extract_seconds;
    j["seconds"] = seconds;
    print_json(j);
    return;
  }
  if (calibrate) print_calibration(cap, c);
  if (!holdout.empty()) print_holdout(holdout);
  if (const auto [mean, worst] = acquire::light_direction_error(cap, c); mean >= 0)
    fmt::print("light directions against the manifest's truth: mean {:.3f} deg, largest {:.3f} deg\n", mean, worst);
  if (extract) {
    fmt::print("{} samples from {} sphere pixels x {} lights into {}:{}; rejected:", r.samples, r.sphere_pixels,
               cap.light_angles_deg.size(), store_path, name);
    for (std::size_t k = 0; k < r.rejected.size(); ++k) fmt::print(" {} {}", acquire::kRejectNames[k], r.rejected[k]);
    fmt::print("\n");
    if (truth_err >= 0)
      fmt::print("against the simulated material: median relative error {:.4f}, median sample / model {:.4f}\n",
                 truth_err, truth_ratio);
    if (suite) {
      const codec::SuiteDiff& d = suite->diff;
      fmt::print(
          "resampled (k = {}, max gap {} deg) against the simulated material under the lighting suite (docs/brdf.md): "
          "CIEDE2000 mean {:.3f}, 95th percentile {:.3f}, max {:.3f}; worst condition {} mean {:.3f}; {} of the "
          "material's {} cells without data (rendered black); cos-weighted relative RMS {:.4f}\n",
          o.grid_k, o.grid_max_gap_deg, d.de00_mean, d.de00_p95, d.de00_max, suite->worst,
          d.conditions[d.worst].de00_mean, d.hole_cells, d.cells, d.rel_rms_cos);
    }
  }
  fmt::print("{:.1f} s{}\n", seconds, o.plots.empty() ? "" : "; plots in " + o.plots);
}

void add_pipeline_options(CLI::App* cmd, AcquireOptions& o, bool calibrates, bool extracts) {
  cmd->add_option("capture", o.capture, "Capture directory (manifest.json)")->required();
  cmd->add_option("-o,--output", o.output, "STORE.h5[:NAME] (NAME: the samples and calibration; default scan)")
      ->required();
  if (calibrates)
    cmd->add_option("--spectral-model", o.spectral, "delta (eq 4.4) or factored (eq 4.6)")->capture_default_str();
  if (calibrates) {
    cmd->add_option("--basis", o.basis, "Filter captures: STORE.h5:BASIS the spectra are solved in");
    cmd->add_option("--filter-solve", o.filter_solve,
                    "Filter captures: wiener (the basis's second moment as prior) or ridge (in the basis)")
        ->capture_default_str();
    cmd->add_option("--filter-noise", o.filter_noise,
                    "Filter captures, wiener: a typical filter's reading noise relative to its white reading (each "
                    "filter's scaled by its recorded readings' noise over the median)")
        ->capture_default_str();
    cmd->add_flag("--equal-filter-noise", o.equal_filter_noise,
                  "Filter captures, wiener: every filter the same relative noise, whatever its exposures");
    cmd->add_option("--ridge", o.ridge, "Filter captures: the solve's regularisation")->capture_default_str();
    cmd->add_option("--filter-terms", o.filter_terms, "Filter captures: response terms fitted per filter (1-4)")
        ->capture_default_str();
    cmd->add_option("--fit-targets", o.fit_targets, "Targets the spectral model is fitted on (default blue,white)")
        ->delimiter(',');
  }
  cmd->add_option("--read-noise", o.read_noise_dn,
                  "The camera's read noise (DN): the samples' variance and filter captures' readings' noise")
      ->capture_default_str();
  cmd->add_option("--electrons-per-dn", o.electrons_per_dn,
                  "The camera's gain: the samples' and filter captures' readings' shot noise")
      ->capture_default_str();
  cmd->add_option("--bias", o.bias_dn, "The camera's bias (DN): subtracted from a dark channel's longest exposure")
      ->capture_default_str();
  cmd->add_flag("--reject-dark-pixels", o.reject_dark,
                "Reject a pixel when any channel is below the linear range at the longest exposure (the reference's "
                "rule); by default it is kept while some channel is in range");
  if (!calibrates) cmd->add_option("--calibration", o.calibration, "Stored calibration to use (default: NAME)");
  cmd->add_option("--plots", o.plots, "Directory for PNG figures");
  if (extracts) {
    cmd->add_option("--plot-theta", o.plot_theta, "theta_i of the incidence-plane plots (degrees)")
        ->delimiter(',')
        ->capture_default_str();
    cmd->add_option("--plot-band", o.plot_band_nm,
                    "Wavelength of the incidence-plane plots (nm; default the middle band)");
    cmd->add_option("--grid-k", o.grid_k,
                    "With a simulated capture's material: resample the samples with this k (as resample -k) and "
                    "compare with the material under the lighting suite")
        ->capture_default_str();
    cmd->add_option("--grid-max-gap", o.grid_max_gap_deg, "The suite check's resampling: as resample --max-gap")
        ->capture_default_str();
    cmd->add_flag("--no-suite{false}", o.suite, "Skip the lighting-suite check against a simulated capture's material");
  }
  cmd->add_flag("--replace", o.replace, "Replace samples or a calibration of the same name");
  cmd->add_flag("--json", o.json, "Print one JSON object");
}

}  // namespace

void setup_acquire(CLI::App& app) {
  auto* cmd = app.add_subcommand("acquire", "From a capture directory to BRDF samples, step by step");
  cmd->require_subcommand(1);
  auto o = std::make_shared<AcquireHdrOptions>();
  auto* hdr = cmd->add_subcommand("hdr", "Merge each light's exposures into HDR images (slope of value against time)");
  hdr->add_option("capture", o->capture, "Capture directory (manifest.json)")->required();
  hdr->add_option("-o,--output", o->output, "Store (.h5) to add hdr-L<index> images to")->required();
  hdr->add_option("--low", o->low, "Lowest value in the linear range (fraction of full scale)")->capture_default_str();
  hdr->add_option("--high", o->high, "Highest value in the linear range (fraction of full scale)")
      ->capture_default_str();
  hdr->add_option("--min-pearson", o->min_pearson, "Fits with a lower Pearson r are flagged non-linear")
      ->capture_default_str();
  hdr->add_flag("--replace", o->replace, "Replace images of the same names");
  hdr->add_flag("--json", o->json, "Print one JSON object");
  hdr->callback([o] { run_acquire_hdr(*o); });

  auto cal = std::make_shared<AcquireOptions>();
  auto* c =
      cmd->add_subcommand("calibrate", "Spatial, spectral, sphere and light calibration, stored under /acquire/NAME");
  add_pipeline_options(c, *cal, true, false);
  c->callback([cal] { run_acquire(*cal, true, false); });
  auto smp = std::make_shared<AcquireOptions>();
  auto* s = cmd->add_subcommand("samples", "Scattered BRDF samples from the capture with a stored calibration");
  add_pipeline_options(s, *smp, false, true);
  s->callback([smp] { run_acquire(*smp, false, true); });
  auto run = std::make_shared<AcquireOptions>();
  auto* r = cmd->add_subcommand("run", "Every step: calibrate, then extract the samples");
  add_pipeline_options(r, *run, true, true);
  r->callback([run] { run_acquire(*run, true, true); });
}

}  // namespace specula::app
