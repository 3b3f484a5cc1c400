// specula relight (reference §4.1.7): an image taken under one light shown under another, relit spectrally
// (eq 4.9: divide out the old light per wavelength, multiply in the new) and as an RGB camera would
// (eq 4.10: per-channel von Kries scaling), side by side, with the CIEDE2000 difference between the two.
#include <fmt/format.h>

#include <algorithm>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/core/relight.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct RelightOptions {
  std::string store;
  std::string image;
  std::string from = "D65";
  std::string to = "A";
  std::string output;
  PreviewOptions preview;
  bool json = false;
};

void run_relight(const RelightOptions& o) {
  const store::Store s = store::Store::open(o.store);
  const store::Cube cube = s.read_image(o.image);
  const WavelengthGrid& grid = cube.wavelengths;
  const Eigen::VectorXd from = parse_illuminant(o.from, grid), to = parse_illuminant(o.to, grid);
  const Relighting r = [&] {
    try {
      return relight(cube_rows(cube), grid, cube_kind(cube), cube.mask, from, to);
    } catch (const InputError& e) {
      throw InputError(s.label() + ": image '" + o.image + "' from " + o.from + ": " + e.what());
    }
  }();

  // Panels: original | spectral relighting | RGB relighting | CIEDE2000 map (0 to 10), all at one exposure.
  PreviewSettings settings = preview_settings(o.preview, grid);
  if (!settings.exposure_stops)
    settings.exposure_stops = auto_exposure_stops(r.original.cwiseMax(r.spectral), cube.mask, SpectrumKind::radiance);
  const std::size_t w = cube.width, h = cube.height;
  std::vector<Picture> panels;
  panels.push_back(render_xyz(r.original, r.white_from, w, h, cube.mask, SpectrumKind::radiance, settings));
  panels.push_back(render_xyz(r.spectral, r.white_to, w, h, cube.mask, SpectrumKind::radiance, settings));
  panels.push_back(render_xyz(r.rgb, r.white_to, w, h, cube.mask, SpectrumKind::radiance, settings));
  Picture& map = panels.emplace_back(Picture{w, h, std::vector<std::uint8_t>(3 * w * h), {}});
  for (std::size_t p = 0; p < w * h; ++p) {
    const Rgb8 c = heat(r.ciede2000[p] / 10.0);
    std::copy(c.begin(), c.end(), map.srgb8.begin() + std::ptrdiff_t(3 * p));
  }
  paint_masked(map.srgb8, cube.mask);
  const Picture out = side_by_side(panels, 4);
  store::write_png_rgb8(o.output, out.width, out.height, out.srgb8);
  if (o.json) {
    Json j;
    j["image"] = o.image;
    j["from"] = o.from;
    j["to"] = o.to;
    j["pixels"] = r.pixels;
    j["mean_ciede2000"] = r.mean_ciede2000;
    j["p95_ciede2000"] = r.p95_ciede2000;
    j["max_ciede2000"] = r.max_ciede2000;
    j["output"] = o.output;
    print_json(j);
  } else {
    fmt::print(
        "{}: relit from {} to {}: mean CIEDE2000 between spectral and RGB relighting {:.3f} "
        "(95th percentile {:.3f}, max {:.3f}) over {} pixels\n",
        o.image, o.from, o.to, r.mean_ciede2000, r.p95_ciede2000, r.max_ciede2000, r.pixels);
    fmt::print("wrote {} (panels: under {}, spectral relighting to {}, RGB relighting to {}, CIEDE2000 map 0-10)\n",
               o.output, o.from, o.to, o.to);
  }
}

}  // namespace

void setup_relight(CLI::App& app) {
  auto o = std::make_shared<RelightOptions>();
  auto* cmd = app.add_subcommand("relight",
                                 "Relight an image spectrally (eq 4.9) and in RGB (eq 4.10); compare with CIEDE2000");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("image", o->image, "Image name")->required();
  cmd->add_option("--from", o->from,
                  "Light the image was taken under (radiance data, whose 99th-percentile luminance is taken as white) "
                  "or shown under (reflectance)")
      ->capture_default_str();
  cmd->add_option("--to", o->to, "New light")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "PNG with the panels side by side")->required();
  cmd->add_flag("--json", o->json, "Print the result as JSON");
  add_preview_options(cmd, o->preview, /*with_illuminant=*/false);
  cmd->callback([o] { run_relight(*o); });
}

}  // namespace specula::app
