// specula export: an object out of the store as spectral OpenEXR, ENVI, CSV, or an sRGB preview
// (8-bit PNG or linear EXR).
#include <fmt/format.h>

#include <optional>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/merl.h"
#include "specula/codec/rgl_bsdf.h"
#include "specula/codec/rgl_export.h"
#include "specula/codec/rgl_scene.h"
#include "specula/codec/rgl_target.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/suite.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/store/io/csv.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct ExportOptions {
  std::string store;
  std::string object;
  std::string output;
  std::string format = "auto";
  std::string interleave = "bsq";
  PreviewOptions preview;
  bool rgb = false;
  std::size_t theta_i = 0, resolution = 0;  // 0: the library's choice (the source's, else 8 and 32)
  std::string parameterisation = "auto";
  std::optional<double> target_de00, target_p95;
  std::vector<std::string> scenes;
};

// The spectral file of `grid` at the smallest resolution whose import the lighting suite finds within the target.
codec::RglBsdf export_to_target(const store::Grid& grid, const codec::RglExportSettings& settings,
                                const ExportOptions& o) {
  const codec::RglTarget target{.de00_mean = *o.target_de00,
                                .de00_p95 = o.target_p95.value_or(codec::default_p95_target(*o.target_de00))};
  codec::RglTargetReport report;
  codec::RglBsdf bsdf =
      codec::export_rgl_to_target(grid, settings, target, codec::LightingSuite(grid.wavelengths), report);
  for (const auto& t : report.trials)
    fmt::print(
        "  {} theta_i x {}^2 samples, {} parameterisation: {} bytes, suite dE00 mean {:.3f}, 95th percentile "
        "{:.3f}{}\n",
        t.theta_i, t.resolution, codec::rgl_parameterisation_name(t.parameterisation), t.bytes, t.de00_mean, t.de00_p95,
        t.met ? " (meets the target)" : "");
  if (!report.reached)
    fmt::print("no resolution tried meets dE00 mean {} and 95th percentile {}; wrote the largest\n", target.de00_mean,
               target.de00_p95);
  return bsdf;
}

// An RGL .bsdf from a BRDF named as STORE.h5 GRID, STORE.h5:GRID, a .spgrid, a .spc or an RGB MERL .binary.
void export_bsdf(const ExportOptions& o) {
  const std::string spec = o.object.empty() ? o.store : o.store + ":" + o.object;
  const codec::RglExportSettings settings{.theta_i = o.theta_i,
                                          .resolution = o.resolution,
                                          .description = "specula export of " + spec,
                                          .parameterisation = codec::parse_rgl_parameterisation(o.parameterisation)};
  const bool merl = std::filesystem::path(spec).extension() == ".binary";
  codec::RglBsdf bsdf;
  if (o.target_p95 && !o.target_de00) throw UsageError("export: --target-p95 goes with --target-de00");
  if (o.target_de00 && o.rgb)
    throw UsageError("export: --target-de00 judges the spectral file under the lighting suite; drop --rgb");
  std::string used;
  if (o.target_de00) {
    bsdf = export_to_target(load_grid(spec, "export", default_uplift_wavelengths()), settings, o);
  } else if (o.rgb && merl) {
    used = codec::rgl_parameterisation_name(codec::rgl_parameterisation_used(nullptr, settings));
    bsdf = codec::export_rgl(codec::read_merl(spec), settings);
  } else {
    const store::Grid grid = load_grid(spec, "export", default_uplift_wavelengths());
    const auto weights = codec::rgb_weights(grid.wavelengths, parse_illuminant(o.preview.illuminant, grid.wavelengths));
    codec::RglParameterisation p;
    bsdf =
        codec::export_rgl_judged(grid, settings, codec::LightingSuite(grid.wavelengths), p, o.rgb ? &weights : nullptr);
    used = codec::rgl_parameterisation_name(p);
  }
  for (const auto& scene : o.scenes)
    if (scene == "pbrt" && bsdf.rgb)
      throw UsageError("export: pbrt-v4 reads spectral .bsdf files only; drop --rgb for --scene pbrt");
  codec::write_rgl_bsdf(o.output, bsdf);
  fmt::print("wrote {} ({}, {} theta_i, {}x{} samples, {} bytes{})\n", o.output,
             bsdf.rgb ? "RGB" : std::to_string(bsdf.channels()) + " wavelengths", bsdf.theta_i.size(), bsdf.resolution,
             bsdf.resolution, std::filesystem::file_size(o.output),
             used.empty() ? "" : ", " + used + " parameterisation");
  const std::filesystem::path out(o.output);
  const std::string name = out.filename().string(), stem = out.stem().string();
  for (const auto& scene : o.scenes) {
    const std::filesystem::path path =
        std::filesystem::path(out).replace_filename(stem + (scene == "pbrt" ? ".pbrt" : ".xml"));
    codec::write_scene(
        path, scene == "pbrt" ? codec::pbrt_scene(name, stem + "_pbrt.exr") : codec::mitsuba_scene(name, !bsdf.rgb));
    fmt::print("wrote {}\n", path.string());
  }
}

std::string format_of(const ExportOptions& o) {
  if (o.format != "auto") return o.format;
  std::string ext = std::filesystem::path(o.output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".exr") return "exr";
  if (ext == ".png") return "png";
  if (ext == ".csv") return "csv";
  if (ext == ".hdr" || ext == ".raw" || ext == ".img" || ext == ".dat" || ext == ".bsq" || ext == ".bil" ||
      ext == ".bip")
    return "envi";
  throw UsageError(o.output + ": cannot tell the format from the extension '" + ext +
                   "'; pass --format exr|envi|png|rgb-exr|csv");
}

void run_export(const ExportOptions& o) {
  if (std::filesystem::path(o.output).extension() == ".bsdf") return export_bsdf(o);
  if (!o.scenes.empty() || o.rgb || o.target_de00 || o.theta_i || o.resolution || o.parameterisation != "auto")
    throw UsageError(
        "export: --rgb, --scene, --target-de00, --theta-i, --resolution and --parameterisation are for .bsdf output");
  if (o.object.empty()) throw UsageError("export: name the object to export from " + o.store);
  const store::Store s = store::Store::open(o.store);
  const auto grids = s.grids();
  if (std::find(grids.begin(), grids.end(), o.object) != grids.end()) {
    // A spectral BRDF grid: an RGB MERL .binary seen under --illuminant, or the grid exchange file.
    const store::Grid grid = s.read_grid(o.object);
    const std::string ext = std::filesystem::path(o.output).extension().string();
    if (ext == ".binary") {
      const auto weights =
          codec::rgb_weights(grid.wavelengths, parse_illuminant(o.preview.illuminant, grid.wavelengths));
      const codec::RgbExport rgb = codec::grid_to_merl(grid, weights);
      codec::write_merl(o.output, rgb.brdf);
      fmt::print("wrote {} (RGB under {}; {} out-of-gamut channel values clamped to 0)\n", o.output,
                 o.preview.illuminant, rgb.clamped);
    } else if (ext == ".spgrid") {
      codec::write_grid_file(o.output, grid);
      fmt::print("wrote {}\n", o.output);
    } else {
      throw UsageError(s.label() + ": '" + o.object +
                       "' is a BRDF grid; export it as an RGB MERL .binary or a .spgrid file");
    }
    return;
  }
  const std::string format = format_of(o);
  const auto collections = s.collections();
  if (std::find(collections.begin(), collections.end(), o.object) != collections.end()) {
    if (format != "csv")
      throw UsageError(s.label() + ": '" + o.object + "' is a collection; export it as .csv (--format csv)");
    store::write_csv_collection(o.output, s.read_collection(o.object));
    fmt::print("wrote {}\n", o.output);
    return;
  }
  if (format == "csv")
    throw UsageError(s.label() + ": '" + o.object + "' is not a collection; CSV export is for collections");
  const store::Cube cube = s.read_image(o.object);
  if (format == "exr") {
    store::write_spectral_exr(o.output, cube);
  } else if (format == "envi") {
    std::filesystem::path data = o.output;
    if (data.extension() == ".hdr") data.replace_extension(".raw");
    const store::Interleave il = o.interleave == "bil"   ? store::Interleave::bil
                                 : o.interleave == "bip" ? store::Interleave::bip
                                                         : store::Interleave::bsq;
    store::write_envi(data, cube, il);
  } else if (format == "png") {
    const Picture p = render(cube, o.preview);
    store::write_png_rgb8(o.output, p.width, p.height, p.srgb8);
  } else if (format == "rgb-exr") {
    const Picture p = render(cube, o.preview);
    store::write_exr_rgb(o.output, p.width, p.height, p.linear);
  } else {
    throw UsageError("--format '" + format + "': use exr, envi, png, rgb-exr or csv");
  }
  fmt::print("wrote {}\n", o.output);
}

}  // namespace

void setup_export(CLI::App& app) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd =
      app.add_subcommand("export", "Write an object as spectral EXR, ENVI, CSV, or an sRGB preview (PNG, linear EXR)");
  cmd->add_option("store", o->store,
                  "Store file; for .bsdf output also a BRDF: STORE.h5:GRID, .spgrid, .spc or RGB MERL .binary")
      ->required();
  cmd->add_option("object", o->object, "Image, collection or BRDF grid name");
  cmd->add_option("-o,--output", o->output,
                  "Output file; the extension picks the format (.exr .hdr .png .csv; .binary .spgrid .bsdf for grids)")
      ->required();
  cmd->add_flag("--rgb", o->rgb, ".bsdf: an RGB file (under --illuminant) instead of the spectral one pbrt-v4 needs");
  cmd->add_option("--theta-i", o->theta_i,
                  ".bsdf: incident elevations (uniform in projected area; default: the source file's for a grid "
                  "imported from a .bsdf, else 8)")
      ->check(CLI::Range(2, 90));
  cmd->add_option("--resolution", o->resolution,
                  ".bsdf: sample grid nodes per side (default: the source file's, else 32)")
      ->check(CLI::Range(2, 512));
  cmd->add_option("--parameterisation", o->parameterisation,
                  ".bsdf: auto (for a grid imported from a .bsdf at its own sizes, export on the source file's "
                  "theta_i, ndf, sigma and vndf (a vndf side above 32 nodes resampled to 32) and on estimated ones and "
                  "keep what the lighting suite finds closer; else estimate), source, or estimate (from the grid "
                  "alone)")
      ->check(CLI::IsMember({"auto", "source", "estimate"}))
      ->capture_default_str();
  cmd->add_option("--target-de00", o->target_de00,
                  ".bsdf: the smallest resolution from --theta-i/--resolution up (ladder in docs/brdf.md) whose import "
                  "the lighting suite finds within this pooled dE00 mean")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--target-p95", o->target_p95, ".bsdf: with --target-de00, the 95th percentile allowed (default 3x)")
      ->check(CLI::PositiveNumber);
  cmd->add_option(
         "--scene", o->scenes,
         ".bsdf: also write a minimal scene beside it: pbrt (pbrt-v4, X.pbrt) and/or mitsuba (Mitsuba 3, X.xml)")
      ->check(CLI::IsMember({"pbrt", "mitsuba"}));
  cmd->add_option("--format", o->format, "auto, exr (spectral), envi, png (sRGB 8-bit), rgb-exr (linear sRGB), csv")
      ->check(CLI::IsMember({"auto", "exr", "envi", "png", "rgb-exr", "csv"}))
      ->capture_default_str();
  cmd->add_option("--interleave", o->interleave, "ENVI interleave: bsq, bil or bip")
      ->check(CLI::IsMember({"bsq", "bil", "bip"}))
      ->capture_default_str();
  add_preview_options(cmd, o->preview);
  cmd->callback([o] { run_export(*o); });
}

}  // namespace specula::app
