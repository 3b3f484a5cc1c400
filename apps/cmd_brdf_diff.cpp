// specula brdf-diff: two spectral BRDF grids compared under the lighting suite (codec/suite.h: CIEDE2000 per
// condition and pooled, holes, cosine-weighted relative RMS, directional albedo), or with --env as rendered on one
// sphere under one spectral environment.
#include <fmt/format.h>

#include <cmath>
#include <optional>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/diff.h"
#include "specula/codec/diff_figure.h"
#include "specula/codec/environment.h"
#include "specula/codec/report_json.h"
#include "specula/codec/suite.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"

namespace specula::app {
namespace {

struct BrdfDiffOptions {
  std::string a, b;
  std::optional<std::string> env;
  std::optional<std::size_t> size;
  std::string panel, heatmap;
  bool json = false;
};

void write_picture(const std::string& path, const Picture& p) {
  store::write_png_rgb8(path, p.width, p.height, p.srgb8);
}

void print_suite(const BrdfDiffOptions& o, const codec::LightingSuite& suite, const codec::SuiteDiff& d) {
  const auto& worst = suite.conditions()[d.worst];
  fmt::print("{} vs {} under the lighting suite ({} conditions, {}-pixel spheres, docs/brdf.md):\n", o.a, o.b,
             d.conditions.size(), suite.size());
  fmt::print("  CIEDE2000 over {} lit pixels: mean {:.3f}, 95th percentile {:.3f}, max {:.3f}\n", d.pixels, d.de00_mean,
             d.de00_p95, d.de00_max);
  fmt::print("  worst condition {}: mean {:.3f}, 95th percentile {:.3f}, max {:.3f}\n", worst.name,
             d.conditions[d.worst].de00_mean, d.conditions[d.worst].de00_p95, d.conditions[d.worst].de00_max);
  fmt::print(
      "  holes: {} of the reference's {} cells have no data in the second grid (rendered black; they light {} of "
      "the suite's pixels); {} cells have data only in the second\n",
      d.hole_cells, d.cells, d.hole_pixels, d.extra_cells);
  fmt::print("  cos-weighted relative RMS {:.4g}\n", d.rel_rms_cos);
  fmt::print("  directional albedo (luminance, D65):");
  for (std::size_t i = 0; i < codec::kSuiteAlbedoAngles.size(); ++i)
    fmt::print(" {:g} deg {:.4g} vs {:.4g} ({:+.2f} %){}", codec::kSuiteAlbedoAngles[i], d.albedo_a[i], d.albedo_b[i],
               100 * (d.albedo_b[i] - d.albedo_a[i]) / (d.albedo_a[i] > 0 ? d.albedo_a[i] : 1),
               i + 1 < codec::kSuiteAlbedoAngles.size() ? "," : "\n");
  fmt::print("  {:<26} {:>7} {:>7} {:>7} {:>6} {:>6}\n", "condition", "mean", "p95", "max", "pixels", "holes");
  for (std::size_t c = 0; c < d.conditions.size(); ++c) {
    const auto& x = d.conditions[c];
    fmt::print("  {:<26} {:7.3f} {:7.3f} {:7.3f} {:6} {:6}\n", suite.conditions()[c].name, x.de00_mean, x.de00_p95,
               x.de00_max, x.pixels, x.hole_pixels);
  }
}

void run_suite_diff(const BrdfDiffOptions& o) {
  auto is_rgb = [](const std::string& spec) { return std::filesystem::path(spec).extension() == ".binary"; };
  const bool b_first = is_rgb(o.a) && !is_rgb(o.b);
  store::Grid a, b;
  (b_first ? b : a) = load_grid(b_first ? o.b : o.a, "brdf-diff", default_uplift_wavelengths());
  const WavelengthGrid grid = (b_first ? b : a).wavelengths;
  (b_first ? a : b) = load_grid(b_first ? o.a : o.b, "brdf-diff", grid);
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError(fmt::format("brdf-diff: {} has {}, {} has {}; compare grids on one wavelength grid", o.a,
                                 a.wavelengths.describe(), o.b, b.wavelengths.describe()));
  const codec::LightingSuite suite(a.wavelengths, {.size = o.size.value_or(64)});
  const codec::SuiteRenders ra = suite.render(a), rb = suite.render(b);
  codec::SuiteDiff d = suite.compare(ra, rb, !o.panel.empty() || !o.heatmap.empty());
  codec::suite_value_metrics(a, b, d);
  if (!o.panel.empty()) write_picture(o.panel, codec::suite_panel(suite, ra, rb, d, false));
  if (!o.heatmap.empty()) write_picture(o.heatmap, codec::suite_panel(suite, ra, rb, d, true));
  if (o.json) {
    fmt::print("{}\n", codec::suite_json(d, suite));
    return;
  }
  print_suite(o, suite, d);
  if (!o.panel.empty())
    fmt::print("  panel ({}: reference | second | CIEDE2000 0 to 2): {}\n", suite.conditions()[d.worst].name, o.panel);
  if (!o.heatmap.empty())
    fmt::print("  CIEDE2000 map of {} (0 to 2 across the ramp): {}\n", suite.conditions()[d.worst].name, o.heatmap);
}

void run_brdf_diff(const BrdfDiffOptions& o) {
  const std::size_t size = o.size.value_or(o.env ? 128 : 64);
  if (size < (o.env ? 8u : 16u) || size > (o.env ? 4096u : 1024u))
    throw UsageError(
        fmt::format("brdf-diff: --size {}: give {} pixels", size, o.env ? "8 to 4096" : "16 to 1024 (suite)"));
  for (const auto& [flag, path] : {std::pair{"--panel", &o.panel}, std::pair{"--heatmap", &o.heatmap}})
    if (!path->empty() && std::filesystem::path(*path).extension() != ".png")
      throw UsageError(fmt::format("brdf-diff: {} must name a .png file, not {}", flag, *path));
  if (!o.env) return run_suite_diff(o);
  // An RGB .binary is uplifted onto the other grid's bands (both .binary: the uplift default); the environment is
  // read once the bands are known, before the second grid.
  auto is_rgb = [](const std::string& spec) { return std::filesystem::path(spec).extension() == ".binary"; };
  const bool b_first = is_rgb(o.a) && !is_rgb(o.b);
  store::Grid a, b;
  (b_first ? b : a) = load_grid(b_first ? o.b : o.a, "brdf-diff", default_uplift_wavelengths());
  const WavelengthGrid grid = (b_first ? b : a).wavelengths;
  const codec::Environment env =
      *o.env == "default" ? codec::default_environment(grid) : codec::read_environment(*o.env, grid);
  (b_first ? a : b) = load_grid(b_first ? o.a : o.b, "brdf-diff", grid);
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError(fmt::format("brdf-diff: {} has {}, {} has {}; compare grids on one wavelength grid", o.a,
                                 a.wavelengths.describe(), o.b, b.wavelengths.describe()));
  const codec::GridDiff d = codec::diff_grids(a, b, env, {.size = size});
  if (!o.panel.empty()) write_picture(o.panel, codec::diff_panel(d.renders, d.de00, false));
  if (!o.heatmap.empty()) write_picture(o.heatmap, codec::diff_panel(d.renders, d.de00, true));
  if (o.json) {
    Json j = {{"a", o.a}, {"b", o.b}};
    j.update(codec::grid_diff_json(d, env.description, size));
    print_json(j);
    return;
  }
  fmt::print("{} vs {} over {} cells valid in both ({} only in the first, {} only in the second):\n", o.a, o.b, d.cells,
             d.only_a, d.only_b);
  fmt::print("  RMS {:.4g} 1/sr, max {:.4g} 1/sr, cos-weighted relative RMS {:.4g}\n", d.rms, d.max_abs, d.rel_rms_cos);
  fmt::print("  rendered under {}: CIEDE2000 mean {:.3f}, 95th percentile {:.3f}, max {:.3f}\n", env.description,
             d.de00_mean, d.de00_p95, d.de00_max);
  if (!o.panel.empty()) fmt::print("  panel: {}\n", o.panel);
  if (!o.heatmap.empty()) fmt::print("  CIEDE2000 map (0 to 2 across the ramp): {}\n", o.heatmap);
}

}  // namespace

void setup_brdf_diff(CLI::App& app) {
  auto o = std::make_shared<BrdfDiffOptions>();
  auto* cmd = app.add_subcommand("brdf-diff",
                                 "Compare two spectral BRDF grids under the lighting suite (CIEDE2000 per "
                                 "condition, holes, albedo), or under one environment (--env)");
  cmd->add_option("a", o->a,
                  "Reference grid: STORE.h5:GRID, a .spgrid file, a .spc (decoded), an RGL .bsdf (RGB ones uplifted), "
                  "or an RGB MERL .binary (uplifted)")
      ->required();
  cmd->add_option("b", o->b,
                  "Grid to compare: STORE.h5:GRID, a .spgrid file, a .spc (decoded), an RGL .bsdf (RGB ones uplifted), "
                  "or an RGB MERL .binary (uplifted)")
      ->required();
  cmd->add_option(
      "--env", o->env,
      "Instead of the suite, one picture under this lighting: 'default' (built-in sky, ground and sun) or a "
      "lat-long EXR (spectral or RGB)");
  cmd->add_option("--size", o->size, "Sphere size in pixels (suite: 64, --env: 128)");
  cmd->add_option("--panel", o->panel,
                  "PNG: the two renderings and the CIEDE2000 map side by side (suite: its worst condition)");
  cmd->add_option("--heatmap", o->heatmap, "PNG: the CIEDE2000 map alone (0 to 2 across the ramp)");
  cmd->add_flag("--json", o->json,
                "Print one JSON object (suite: pooled and every condition; --env: rms, de00_mean, ...)");
  cmd->callback([o] { run_brdf_diff(*o); });
}

}  // namespace specula::app
