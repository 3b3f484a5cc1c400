// specula brdf-diff: two spectral BRDF grids compared over the grid (RMS, max, cosine-weighted relative RMS)
// and as rendered on a sphere under a spectral environment (CIEDE2000 mean and 95th percentile).
#include <fmt/format.h>

#include <cmath>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/diff.h"
#include "specula/codec/environment.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"

namespace specula::app {
namespace {

struct BrdfDiffOptions {
  std::string a, b;
  std::string env = "default";
  std::size_t size = 128;
  std::string panel, heatmap;
  bool json = false;
};

// sRGB of an XYZ rendering, the white mapped to 1 after adaptation to D65; off-sphere pixels dark grey.
void paint(const codec::SphereRenders& r, const std::vector<float>& xyz, std::vector<std::uint8_t>& rgb, std::size_t stride,
           std::size_t x0) {
  const Eigen::Matrix3d m = rendering_to_linear_srgb(r.white);
  for (std::size_t y = 0; y < r.size; ++y)
    for (std::size_t x = 0; x < r.size; ++x) {
      const std::size_t p = y * r.size + x;
      const Eigen::Vector3d c = m * Eigen::Vector3d(xyz[3 * p], xyz[3 * p + 1], xyz[3 * p + 2]);
      for (std::size_t k = 0; k < 3; ++k)
        rgb[3 * (y * stride + x0 + x) + k] = r.covered[p] ? std::uint8_t(std::lround(255 * srgb_encode(c[Eigen::Index(k)]))) : 24;
    }
}

void run_brdf_diff(const BrdfDiffOptions& o) {
  if (o.size < 8 || o.size > 4096) throw UsageError("brdf-diff: --size " + std::to_string(o.size) + ": give 8 to 4096 pixels");
  for (const auto& [flag, path] : {std::pair{"--panel", &o.panel}, std::pair{"--heatmap", &o.heatmap}})
    if (!path->empty() && std::filesystem::path(*path).extension() != ".png")
      throw UsageError(fmt::format("brdf-diff: {} must name a .png file, not {}", flag, *path));
  // An RGB .binary is uplifted onto the other grid's bands (both .binary: the uplift default); the environment is
  // read once the bands are known, before the second grid.
  auto is_rgb = [](const std::string& spec) { return std::filesystem::path(spec).extension() == ".binary"; };
  const bool b_first = is_rgb(o.a) && !is_rgb(o.b);
  store::Grid a, b;
  (b_first ? b : a) = load_grid(b_first ? o.b : o.a, "brdf-diff", default_uplift_wavelengths());
  const WavelengthGrid grid = (b_first ? b : a).wavelengths;
  const codec::Environment env = o.env == "default" ? codec::default_environment(grid) : codec::read_environment(o.env, grid);
  (b_first ? a : b) = load_grid(b_first ? o.a : o.b, "brdf-diff", grid);
  if (!a.wavelengths.approx_equal(b.wavelengths))
    throw InputError(fmt::format("brdf-diff: {} has {}, {} has {}; compare grids on one wavelength grid", o.a,
                                 a.wavelengths.describe(), o.b, b.wavelengths.describe()));
  const codec::GridDiff d = codec::diff_grids(a, b, env, {.size = o.size});
  if (!o.panel.empty()) {
    // A | B | CIEDE2000 heat map (0 to 2 across the ramp).
    const std::size_t n = o.size, w = 3 * n;
    std::vector<std::uint8_t> rgb(3 * w * n, 24);
    paint(d.renders, d.renders.xyz[0], rgb, w, 0);
    paint(d.renders, d.renders.xyz[1], rgb, w, n);
    for (std::size_t p = 0; p < n * n; ++p) {
      if (!d.renders.covered[p]) continue;
      const auto c = heat(std::min(1.0, d.de00[p] / 2.0));
      for (std::size_t k = 0; k < 3; ++k) rgb[3 * ((p / n) * w + 2 * n + p % n) + k] = c[k];
    }
    store::write_png_rgb8(o.panel, w, n, rgb);
  }
  if (!o.heatmap.empty()) {
    const std::size_t n = o.size;
    std::vector<std::uint8_t> rgb(3 * n * n, 24);
    for (std::size_t p = 0; p < n * n; ++p)
      if (d.renders.covered[p]) {
        const auto c = heat(std::min(1.0, d.de00[p] / 2.0));
        for (std::size_t k = 0; k < 3; ++k) rgb[3 * p + k] = c[k];
      }
    store::write_png_rgb8(o.heatmap, n, n, rgb);
  }
  if (o.json) {
    fmt::print(R"({{"a":{},"b":{},"environment":{},"cells":{},"only_a":{},"only_b":{},"rms":{},"max_abs":{},)"
               R"("rel_rms_cos":{},"de00_mean":{},"de00_p95":{},"de00_max":{},"size":{}}})"
               "\n",
               json_string(o.a), json_string(o.b), json_string(env.description), d.cells, d.only_a, d.only_b, d.rms,
               d.max_abs, d.rel_rms_cos, d.de00_mean, d.de00_p95, d.de00_max, o.size);
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
  auto* cmd = app.add_subcommand("brdf-diff", "Compare two spectral BRDF grids: values, and renderings (CIEDE2000)");
  cmd->add_option("a", o->a, "Reference grid: STORE.h5:GRID, a .spgrid file, a .spc (decoded), an RGL .bsdf (RGB ones uplifted), or an RGB MERL .binary (uplifted)")->required();
  cmd->add_option("b", o->b, "Grid to compare: STORE.h5:GRID, a .spgrid file, a .spc (decoded), an RGL .bsdf (RGB ones uplifted), or an RGB MERL .binary (uplifted)")->required();
  cmd->add_option("--env", o->env, "Lighting: 'default' (built-in sky, ground and sun) or a lat-long EXR (spectral or RGB)")
      ->capture_default_str();
  cmd->add_option("--size", o->size, "Sphere size in pixels")->capture_default_str();
  cmd->add_option("--panel", o->panel, "PNG: the two renderings and the CIEDE2000 map side by side");
  cmd->add_option("--heatmap", o->heatmap, "PNG: the CIEDE2000 map alone (0 to 2 across the ramp)");
  cmd->add_flag("--json", o->json, "Print one JSON object (rms, max_abs, rel_rms_cos, de00_mean, de00_p95, ...)");
  cmd->callback([o] { run_brdf_diff(*o); });
}

}  // namespace specula::app
