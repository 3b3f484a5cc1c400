// specula render: a sphere under one directional light, from an RGB MERL .binary, a spectral grid file, a store
// grid (STORE.h5:NAME) or a .spc (evaluated from its coefficients, never decoded to a grid), spectral ones rendered
// through the CIE CMFs under --illuminant; or, with --env, a spectral rendering under an environment (an RGB
// .binary uplifted first); sRGB PNG and linear EXR.
#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/environment.h"
#include "specula/codec/merl.h"
#include "specula/codec/render.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_eval.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct RenderOptions {
  std::string input;
  std::string output;
  std::size_t size = 256;
  std::vector<double> light = {45, 135};
  std::string illuminant = "D65";
  double exposure = 0;
  std::string env;
};

codec::SpcBrdf load_spc(const std::string& path) {
  return codec::SpcBrdf(codec::decode_spc_coefficients(codec::read_spc_file(path), path));
}

// An RGB .binary as it is, a spectral grid seen under --illuminant.
codec::SphereImage render_rgb(const RenderOptions& o, const Eigen::Vector3d& light) {
  if (std::filesystem::path(o.input).extension() == ".binary")
    return codec::render_sphere(codec::read_merl(o.input), o.size, light);
  if (std::filesystem::path(o.input).extension() == ".bsdf") {
    const codec::RglBsdf b = codec::read_rgl_bsdf(o.input);
    if (b.rgb) return codec::render_sphere(codec::rgl_to_merl(b), o.size, light);
  }
  const store::Grid grid = load_grid(o.input, "render");
  return codec::render_sphere(grid, parse_illuminant(o.illuminant, grid.wavelengths), o.size, light);
}

void run_render(const RenderOptions& o) {
  if (o.light.size() != 2 || !(o.light[0] >= 0 && o.light[0] < 90) || !std::isfinite(o.light[1]))
    throw UsageError("render: --light THETA,PHI in degrees with 0 <= THETA < 90 (angle from the viewer)");
  if (!(std::abs(o.exposure) <= 64)) throw UsageError("render: --exposure must be between -64 and 64 stops");
  std::filesystem::path png(o.output);
  if (png.extension() != ".png") throw UsageError("render: -o must name a .png file (the EXR is written beside it)");
  const std::filesystem::path exr = std::filesystem::path(png).replace_extension(".exr");
  const bool coded = std::filesystem::path(o.input).extension() == ".spc";
  if (!o.env.empty()) {
    auto environment = [&](const WavelengthGrid& wavelengths) {
      return o.env == "default" ? codec::default_environment(wavelengths) : codec::read_environment(o.env, wavelengths);
    };
    codec::Environment env;
    codec::SphereRenders r;
    std::string note;
    if (coded) {
      const codec::SpcBrdf brdf = load_spc(o.input);
      env = environment(brdf.wavelengths());
      const codec::SpcBrdf* brdfs[] = {&brdf};
      r = codec::render_spheres(brdfs, env, o.size);
      note = " (evaluated from its " + std::to_string(brdf.k()) + " coefficients per cell)";
    } else {
      const store::Grid grid = load_grid(o.input, "render", default_uplift_wavelengths());
      env = environment(grid.wavelengths);
      r = codec::render_spheres({&grid}, env, o.size);
      if (grid.provenance.importer == "uplift-clamp") note = " (uplifted to " + grid.wavelengths.describe() + ")";
    }
    const std::vector<float> linear = codec::linear_srgb(r, env.description).linear;
    std::vector<std::uint8_t> srgb(3 * o.size * o.size);
    encode_srgb8(linear, r.covered, o.exposure, srgb);
    store::write_png_rgb8(png, o.size, o.size, srgb);
    store::write_exr_rgb(exr, o.size, o.size, linear);
    fmt::print("rendered {}{} on a {}x{} sphere under {}: {} and {}\n", o.input, note, o.size, o.size, env.description,
               png.string(), exr.string());
    return;
  }
  const double t = o.light[0] * std::numbers::pi / 180, p = o.light[1] * std::numbers::pi / 180;
  const Eigen::Vector3d light(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
  codec::SphereImage img;
  if (coded) {
    const codec::SpcBrdf brdf = load_spc(o.input);
    img = codec::render_sphere(
        brdf, codec::rgb_weights(brdf.wavelengths(), parse_illuminant(o.illuminant, brdf.wavelengths())), o.size,
        light);
  } else {
    img = render_rgb(o, light);
  }
  std::vector<std::uint8_t> srgb(3 * o.size * o.size);
  encode_srgb8(img.linear, img.covered, o.exposure, srgb);
  store::write_png_rgb8(png, o.size, o.size, srgb);
  store::write_exr_rgb(exr, o.size, o.size, img.linear);
  fmt::print("rendered {} on a {}x{} sphere, light at theta {} phi {} deg: {} and {}\n", o.input, o.size, o.size,
             o.light[0], o.light[1], png.string(), exr.string());
}

}  // namespace

void setup_render(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "A sphere under a directional light from a BRDF (sRGB PNG and linear EXR)");
  cmd->add_option("brdf", o->input,
                  "MERL .binary, spectral grid file, STORE.h5:GRID, an RGL .bsdf, or a .spc (evaluated from its code, "
                  "not decoded)")
      ->required();
  cmd->add_option("-o,--output", o->output, "PNG to write; the linear EXR goes beside it")->required();
  cmd->add_option("--size", o->size, "Image width and height in pixels")->capture_default_str();
  cmd->add_option("--light", o->light, "Light direction THETA,PHI in degrees (theta from the viewer)")
      ->delimiter(',')
      ->expected(2)
      ->capture_default_str();
  cmd->add_option("--illuminant", o->illuminant,
                  "Light SPD for spectral grids: D65, D50, A, E, D<CCT>, blackbody:K or CSV")
      ->capture_default_str();
  cmd->add_option("--env", o->env,
                  "Light by a spectral environment instead: 'default' (built-in sky, ground, sun) or a lat-long EXR "
                  "(spectral or RGB); a .binary is uplifted to 400-700 nm step 10");
  cmd->add_option("--exposure", o->exposure, "Stops of gain before sRGB encoding of the PNG")->capture_default_str();
  cmd->callback([o] { run_render(*o); });
}

}  // namespace specula::app
