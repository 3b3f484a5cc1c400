#include "apps/common.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "specula/codec/merl.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/spc.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/uplift.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/store/object_spec.h"

namespace specula::app {
namespace {
std::string g_command_line;

}  // namespace

const std::string& command_line() { return g_command_line; }

void set_command_line(int argc, char** argv) {
  g_command_line.clear();
  for (int i = 0; i < argc; ++i) {
    if (i) g_command_line += ' ';
    const std::string a = argv[i];
    const bool quote = a.empty() || a.find_first_of(" \t'\"$") != std::string::npos;
    g_command_line += quote ? "'" + a + "'" : a;
  }
}

void add_preview_options(CLI::App* cmd, PreviewOptions& o, bool with_illuminant) {
  if (with_illuminant)
    cmd->add_option("--illuminant", o.illuminant,
                    "Light for reflectance data: D65, D50, A, E, D<CCT/100>, blackbody:K or an SPD CSV file")
        ->capture_default_str();
  cmd->add_option("--exposure", o.exposure, "Exposure in stops, or 'auto'")->capture_default_str();
  cmd->add_option("--tone", o.tone, "Tone mapping: clip or reinhard")
      ->check(CLI::IsMember({"clip", "reinhard"}))
      ->capture_default_str();
  cmd->add_flag("--no-desaturate", o.no_desaturate, "Clip out-of-gamut colours instead of desaturating them");
  cmd->add_flag("--no-adapt", o.no_adapt, "Do not adapt the scene white to D65");
}

PreviewSettings preview_settings(const PreviewOptions& o, const WavelengthGrid& grid) {
  PreviewSettings p;
  p.illuminant = parse_illuminant(o.illuminant, grid);
  try {
    p.exposure_stops = parse_exposure(o.exposure);
  } catch (const UsageError&) {
    throw UsageError("--exposure '" + o.exposure + "': give stops between -64 and 64, or auto");
  }
  p.tone = parse_tone(o.tone);
  p.desaturate = !o.no_desaturate;
  p.adapt_to_d65 = !o.no_adapt;
  return p;
}

Eigen::Map<const RowMatrixXf> cube_rows(const Cube& cube) {
  return {cube.data.data(), Eigen::Index(cube.height * cube.width), Eigen::Index(cube.bands)};
}

SpectrumKind cube_kind(const Cube& cube) {
  return cube.units == "reflectance" ? SpectrumKind::reflectance : SpectrumKind::radiance;
}

Picture render(const Cube& cube, const PreviewOptions& o) {
  return render(cube, preview_settings(o, cube.wavelengths));
}

Picture render(const Cube& cube, const PreviewSettings& settings) {
  return render_preview(cube_rows(cube), cube.width, cube.height, cube.wavelengths, cube_kind(cube), cube.mask,
                        settings);
}

Json json_numbers(std::span<const double> v) { return Json(std::vector<double>(v.begin(), v.end())); }

Json json_numbers(const Eigen::VectorXd& v) {
  return json_numbers(std::span<const double>(v.data(), std::size_t(v.size())));
}

void print_json(const Json& j) { fmt::print("{}\n", j.dump(-1, ' ', false, Json::error_handler_t::replace)); }

std::vector<store::Store> open_stores(const std::vector<std::string>& paths) {
  std::vector<store::Store> stores;
  for (const auto& p : paths) stores.push_back(store::Store::open(p));
  return stores;
}

std::string basis_output(const std::vector<std::string>& inputs, const std::string& output) {
  if (!output.empty()) return output;
  if (inputs.empty()) throw UsageError("no input store given");
  return inputs.front();
}

namespace {
// "path.h5:name" where path.h5 exists (or, when writing, ends in .h5) and the whole spec is not a file.
std::optional<std::pair<std::string, std::string>> store_spec(const std::string& spec, bool writing) {
  const auto s = store::parse_object_spec(spec);
  if (!s || s->name.empty() || std::filesystem::exists(spec)) return std::nullopt;
  if (std::filesystem::is_regular_file(s->file) || (writing && s->file.extension() == ".h5"))
    return std::pair{s->file.string(), s->name};
  return std::nullopt;
}
}  // namespace

store::Grid load_grid(const std::string& spec, const std::string& command,
                      const std::optional<WavelengthGrid>& uplift_onto) {
  if (const auto s = store_spec(spec, false)) return store::Store::open(s->first).read_grid(s->second);
  const std::filesystem::path in(spec);
  if (in.extension() == ".h5")
    throw UsageError(command + ": " + spec + " is a store; name the grid as " + spec + ":GRID (see `specula ls " +
                     spec + "`)");
  std::optional<codec::RglBsdf> rgl;
  if (in.extension() == ".bsdf") {
    rgl = codec::read_rgl_bsdf(in);
    if (!rgl->rgb) return codec::rgl_to_grid(*rgl, spec);
  }
  if (in.extension() == ".binary" || rgl) {
    if (!uplift_onto)
      throw UsageError(
          command + ": " + spec +
          (rgl ? " is an RGB RGL file; make a spectral grid of it with `specula import " + spec + " -o STORE.h5` first"
               : " is an RGB MERL file; make a spectral grid of it with `specula uplift` first"));
    const codec::Uplift uplift(codec::rgb_weights(*uplift_onto, illuminant("D65", *uplift_onto)),
                               codec::kDefaultUpliftAlpha);
    store::Grid g = codec::uplift_merl(rgl ? codec::rgl_to_merl(*rgl) : codec::read_merl(in), *uplift_onto, uplift,
                                       codec::UpliftMethod::clamp);
    g.provenance.source_file = spec;
    g.provenance.importer = "uplift-clamp";
    if (rgl) g.parameterisation = codec::rgl_parameterisation(*rgl);
    return g;
  }
  if (in.extension() == ".spc") return codec::decode_spc(codec::read_spc_file(in), spec);
  return codec::read_grid_file(in);
}

WavelengthGrid default_uplift_wavelengths() { return WavelengthGrid::range(400, 700, 10); }

std::string save_grid(const store::Grid& grid, const std::string& spec, bool replace, const std::string& command) {
  if (const auto s = store_spec(spec, true)) {
    store::StoreWriter w(s->first, {.compression = {}, .replace = replace, .command_line = command_line()});
    w.add_grid(s->second, grid);
    w.commit();
    return "grid '" + s->second + "' in " + s->first;
  }
  const std::filesystem::path out(spec);
  if (out.extension() == ".binary") {
    const auto weights = codec::rgb_weights(grid.wavelengths, illuminant("D65", grid.wavelengths));
    const auto rgb = codec::grid_to_merl(grid, weights);
    codec::write_merl(out, rgb.brdf);
    return "RGB MERL file " + spec +
           (rgb.clamped ? " (" + std::to_string(rgb.clamped) + " out-of-gamut values clamped)" : "");
  }
  if (out.extension() == ".h5") throw UsageError(command + ": name the grid to write as " + spec + ":NAME");
  if (out.extension() != ".spgrid")
    throw UsageError(command + ": " + spec + ": write STORE.h5:NAME, a .spgrid exchange file or an RGB .binary");
  codec::write_grid_file(out, grid);
  return "spectral grid file " + spec;
}

}  // namespace specula::app
