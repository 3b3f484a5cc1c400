// specula resample-study: the reference's evaluation of resampling (§5.4, figures 5.9-5.17). The study's
// Torrance-Sparrow and Ward materials are sampled at the configurations of a simulated scan (acquire/scan.h),
// reconstructed on the MERL grid for each mapping, k and weighting, rendered on a sphere under one directional
// light and compared with the analytic model per pixel; and, per mapping, the whole grid resampled and compared with
// the material under the lighting suite (docs/brdf.md), the project's one fidelity measure. Prints the tables; --out
// adds the renders (one PNG sheet per material) and the incidence-plane plot of figure 5.17.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/gnuplot.h"
#include "specula/acquire/plane_plot.h"
#include "specula/acquire/scan.h"
#include "specula/acquire/study.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/brdf_resample.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/store/io/png_stack.h"

namespace specula::app {
namespace {

using std::numbers::pi;

struct ResampleStudyOptions {
  std::vector<std::string> materials = {"study-ts", "study-ward"};
  acquire::ScanRig rig;
  std::vector<std::size_t> ks = {1, 16, 64, 256};
  std::size_t render_size = 200;
  std::vector<double> light = {45, 135};
  double max_gap_deg = brdf::kDefaultMaxGapDegrees;
  std::size_t plot_k = 32;
  std::size_t suite_k = 32;
  bool suite = true;
  std::string out;
  bool json = false;
};

std::string row_label(const acquire::StudyResult& r) {
  const char* m = r.mapping == brdf::Mapping::standard ? "M_s" : r.mapping == brdf::Mapping::marschner ? "M_m" : "M_h";
  return r.k == 1 ? std::string(m)
                  : fmt::format("{}, {}", m, r.weights == brdf::Weights::mean ? "Avg." : "Weighted Avg.");
}

// Figure 5.17: samples within 2 degrees of theta_i = 45 degrees and of the incidence plane (cube root of the BRDF
// against the signed outgoing angle: positive towards the mirror direction), the reconstruction (M_s, k, Shepard)
// looked up in the grid along the plane, and the model.
void incidence_plot(const std::filesystem::path& path, const std::string& material, const brdf::SpectralModel& model,
                    std::span<const double> angles, std::span<const float> values, std::size_t k, double max_gap) {
  const auto gnuplot = find_gnuplot();
  if (gnuplot.empty())
    throw UsageError("resample-study: --out draws the incidence-plane plot with gnuplot; install it");
  const double ti = pi / 4, eps = 2 * pi / 180;
  const brdf::Resampler r(angles, values, 1, {.k = k, .weights = brdf::Weights::shepard, .max_gap = max_gap});
  std::string script = "$S << EOD\n" +
                       acquire::plane_points_table(acquire::incidence_plane_points(angles, values, 1, ti, eps, 0)) +
                       "EOD\n$R << EOD\n" + acquire::grid_plane_table(r, model, ti) + "EOD\n";
  script += "set grid\nset key top left\nset xlabel 'theta_o (degrees; negative: same side as the light)'\n";
  script += "set ylabel 'cube root of the BRDF (1/sr)'\nset xrange [-90:90]\n";
  script += "set title " +
            gnuplot_quote(fmt::format("{}: incidence plane at theta_i = 45 deg, samples within 2 deg; "
                                      "M_s, k = {}, Shepard (grid lookup)",
                                      material, k)) +
            " noenhanced\n";
  script +=
      "plot $S using 1:2 with points pt 7 ps 0.4 lc rgb '#808080' title 'samples', "
      "$R using 1:3 with lines lw 2 lc rgb '#2060c0' title 'model', "
      "$R using 1:2 with lines lw 2 lc rgb '#d04020' title 'reconstruction'\n";
  plot_png(gnuplot, path, gnuplot_png_terminal(1000, 600), script);
}

// One mapping's whole grid, resampled from the scan at suite_k (Shepard), against the material under the suite.
struct SuiteRow {
  brdf::Mapping mapping;
  codec::SuiteDiff diff;
  std::string worst;
};

// The study materials are grey, so 16 bands (400-700 nm) show the suite all there is; the scan's samples of `name`
// there, resampled per mapping onto every cell, and the material evaluated at every cell as the reference.
std::vector<SuiteRow> suite_rows(const std::string& name, const std::vector<double>& angles,
                                 const ResampleStudyOptions& o) {
  const WavelengthGrid bands = WavelengthGrid::range(400, 700, 20);
  const auto model = brdf::make_material(name, bands);
  const std::size_t n = angles.size() / 4, b = bands.size();
  std::vector<float> values(n * b);
  brdf::evaluate_at(*model, angles, values);
  store::Grid truth;
  truth.wavelengths = bands;
  truth.brdf.resize(b * brdf::kMerlCells);
  brdf::evaluate_grid(*model, truth.brdf);
  const codec::LightingSuite suite(bands);
  const brdf::MemorySamples samples(angles, values, b);
  std::vector<SuiteRow> rows;
  for (const auto mapping : {brdf::Mapping::standard, brdf::Mapping::marschner, brdf::Mapping::halfdiff}) {
    check_interrupt();
    store::Grid grid;
    grid.wavelengths = bands;
    grid.brdf.resize(b * brdf::kMerlCells);
    const brdf::ResampleOptions ro{.mapping = mapping, .k = o.suite_k, .max_gap = o.max_gap_deg * pi / 180};
    brdf::resample_grid(samples, ro, grid.brdf);
    SuiteRow r{mapping, codec::suite_diff(truth, grid, suite), ""};
    r.worst = suite.conditions()[r.diff.worst].name;
    rows.push_back(std::move(r));
  }
  return rows;
}

Json suite_rows_json(const std::vector<SuiteRow>& rows, std::size_t k) {
  Json j = Json::array();
  for (const auto& r : rows)
    j.push_back({{"mapping", std::string(brdf::mapping_name(r.mapping))},
                 {"k", k},
                 {"weights", "shepard"},
                 {"de00_mean", r.diff.de00_mean},
                 {"de00_p95", r.diff.de00_p95},
                 {"de00_max", r.diff.de00_max},
                 {"worst_condition", r.worst},
                 {"worst_de00_mean", r.diff.conditions[r.diff.worst].de00_mean},
                 {"cells", r.diff.cells},
                 {"hole_cells", r.diff.hole_cells}});
  return j;
}

void print_suite_rows(const std::string& name, const std::vector<SuiteRow>& rows, std::size_t k) {
  fmt::print(
      "| {} under the lighting suite (whole grid, k = {}, Shepard) | CIEDE2000 mean | p95 | max | worst condition "
      "(mean) | cells without data |\n|---|---|---|---|---|---|\n",
      name, k);
  for (const auto& r : rows)
    fmt::print("| {} | {:.3f} | {:.3f} | {:.3f} | {} ({:.3f}) | {} of {} |\n", brdf::mapping_name(r.mapping),
               r.diff.de00_mean, r.diff.de00_p95, r.diff.de00_max, r.worst, r.diff.conditions[r.diff.worst].de00_mean,
               r.diff.hole_cells, r.diff.cells);
  fmt::print("\n");
}

void run_resample_study(const ResampleStudyOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (o.light.size() != 2 || !(o.light[0] >= 0 && o.light[0] < 90) || !std::isfinite(o.light[1]))
    throw UsageError("resample-study: --light THETA,PHI in degrees with 0 <= THETA < 90 (angle from the viewer)");
  if (!(o.max_gap_deg > 0 && o.max_gap_deg <= 180)) throw UsageError("--max-gap: give degrees in (0, 180]");
  if (o.render_size < 8 || o.render_size > 2048) throw UsageError("--render-size: give 8 to 2048 pixels");
  for (const auto k : o.ks)
    if (k < 1 || k > 100000) throw UsageError("-k: every value must be 1 to 100000");
  if (o.suite_k < 1 || o.suite_k > 100000) throw UsageError("--suite-k: give 1 to 100000");
  const WavelengthGrid band({550.0});
  for (const auto& m : o.materials) brdf::make_material(m, band);
  acquire::StudyOptions so;
  so.ks = o.ks;
  so.render_size = o.render_size;
  const double lt = o.light[0] * pi / 180, lp = o.light[1] * pi / 180;
  so.light = brdf::direction(lt, lp);
  so.max_gap = o.max_gap_deg * pi / 180;
  if (!o.out.empty()) std::filesystem::create_directories(o.out);

  const std::vector<acquire::ScanPixel> pixels = acquire::scan_pixels(o.rig);
  std::vector<double> angles;
  for (std::size_t j = 0; j < o.rig.lights; ++j) acquire::scan_light(o.rig, pixels, j, angles);
  const std::size_t n = angles.size() / 4;
  Json json = Json::array();
  for (const auto& name : o.materials) {
    check_interrupt();
    const auto model = brdf::make_material(name, band);
    std::vector<float> values(n);
    brdf::evaluate_at(*model, angles, values);
    const acquire::StudyOutput s = acquire::resampling_study(*model, 0, angles, values, so);
    const std::vector<SuiteRow> suite = o.suite ? suite_rows(name, angles, o) : std::vector<SuiteRow>();
    if (!o.out.empty()) {
      const acquire::Rgb8Sheet sheet = acquire::study_sheet(s, 2 * o.ks.size() - 1);
      store::write_png_rgb8(std::filesystem::path(o.out) / (name + "-renders.png"), sheet.width, sheet.height,
                            sheet.rgb);
      incidence_plot(std::filesystem::path(o.out) / (name + "-incidence.png"), name, *model, angles, values, o.plot_k,
                     so.max_gap);
    }
    if (o.json) {
      Json rows = Json::array();
      for (const auto& r : s.rows)
        rows.push_back({{"mapping", std::string(brdf::mapping_name(r.mapping))},
                        {"k", r.k},
                        {"weights", r.k == 1 ? std::string("nearest") : std::string(brdf::weights_name(r.weights))},
                        {"l1", r.l1},
                        {"max_error", r.max_error},
                        {"pixels_without_data", r.pixels_without_data}});
      json.push_back({{"material", name},
                      {"description", brdf::material_catalogue().at(name)},
                      {"samples", n},
                      {"grid_l1", s.grid_l1},
                      {"rows", std::move(rows)},
                      {"suite", suite_rows_json(suite, o.suite_k)}});
      continue;
    }
    fmt::print("{} ({}): {} scan samples ({} sphere pixels x {} lights), {}x{} render, light at theta {} phi {} deg\n",
               name, brdf::material_catalogue().at(name), n, pixels.size(), o.rig.lights, o.render_size, o.render_size,
               o.light[0], o.light[1]);
    fmt::print("the model at cell centres (grid quantisation alone): average L1 error per pixel {:.6f}\n\n", s.grid_l1);
    for (const std::size_t k : o.ks) {
      fmt::print("| {} k = {} | avg. L1 error per pixel | max | pixels without data |\n|---|---|---|---|\n", name, k);
      for (const auto& r : s.rows)
        if (r.k == k)
          fmt::print("| {} | {:.6f} | {:.4f} | {} |\n", row_label(r), r.l1, r.max_error, r.pixels_without_data);
      fmt::print("\n");
    }
    if (o.suite) print_suite_rows(name, suite, o.suite_k);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    Json j;
    j["samples"] = n;
    j["render_size"] = o.render_size;
    j["materials"] = std::move(json);
    j["seconds"] = seconds;
    print_json(j);
    return;
  }
  fmt::print("{:.1f} s{}\n", seconds, o.out.empty() ? "" : "; renders and incidence-plane plots in " + o.out);
}

}  // namespace

void setup_resample_study(CLI::App& app) {
  auto o = std::make_shared<ResampleStudyOptions>();
  auto* cmd =
      app.add_subcommand("resample-study",
                         "The reference's resampling study (§5.4): scan samples of analytic BRDFs reconstructed per "
                         "mapping, k and weighting, rendered and compared");
  cmd->add_option("--material", o->materials, "Materials (see synth-samples)")->delimiter(',')->capture_default_str();
  cmd->add_option("-k", o->ks, "Neighbour counts")->delimiter(',')->capture_default_str();
  cmd->add_option("--sphere-px", o->rig.sphere_px, "Scan: the sphere's diameter on the image (pixels)")
      ->capture_default_str();
  cmd->add_option("--lights", o->rig.lights, "Scan: light positions on the arc")->capture_default_str();
  cmd->add_option("--render-size", o->render_size, "Rendered sphere's size (pixels)")->capture_default_str();
  cmd->add_option("--light", o->light, "Render light THETA,PHI in degrees (theta from the viewer)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--max-gap", o->max_gap_deg, "Cells farther than this from every sample have no data (degrees)")
      ->capture_default_str();
  cmd->add_option("--plot-k", o->plot_k, "k of the incidence-plane plot (M_s, Shepard)")->capture_default_str();
  cmd->add_option("--suite-k", o->suite_k,
                  "k of the whole-grid resamplings (Shepard, one per mapping) compared under the lighting suite")
      ->capture_default_str();
  cmd->add_flag("--no-suite{false}", o->suite, "Skip the lighting-suite comparison");
  cmd->add_option("--out", o->out, "Directory for the render sheets and incidence-plane plots (PNG)");
  cmd->add_flag("--json", o->json, "Print one JSON object with every result");
  cmd->callback([o] { run_resample_study(*o); });
}

}  // namespace specula::app
