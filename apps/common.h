#pragma once
// What the subcommands share: provenance of the command line, illuminant and preview options,
// a cube rendered through core/preview.h, JSON output.
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "specula/core/colour.h"
#include "specula/core/preview.h"
#include "specula/store/cube.h"
#include "specula/store/store.h"

namespace specula::app {

using store::Cube;

/// The command line as typed, recorded as provenance.
const std::string& command_line();
/// Remembers argv for command_line().
void set_command_line(int argc, char** argv);

/// Options that turn spectra into an sRGB picture, as typed on the command line.
struct PreviewOptions {
  std::string illuminant = "D65";
  std::string exposure = "auto";
  std::string tone = "clip";
  bool no_desaturate = false;
  bool no_adapt = false;
};
/// Registers --exposure, --tone, --no-desaturate, --no-adapt (and --illuminant when asked) on `cmd`.
void add_preview_options(CLI::App* cmd, PreviewOptions& o, bool with_illuminant = true);
/// The settings the options name, the illuminant on `grid`; errors name the flag.
PreviewSettings preview_settings(const PreviewOptions& o, const WavelengthGrid& grid);
/// A cube's spectra as rows (one per pixel) and what its units say they are.
Eigen::Map<const RowMatrixXf> cube_rows(const Cube& cube);
SpectrumKind cube_kind(const Cube& cube);
/// Renders `cube` through render_preview (reflectance lit by the illuminant, radiance as is).
Picture render(const Cube& cube, const PreviewOptions& o);
/// The same with settings already made.
Picture render(const Cube& cube, const PreviewSettings& settings);

/// The numbers as a JSON array (non-finite ones null), in the order of the output objects' keys.
using Json = nlohmann::ordered_json;
Json json_numbers(std::span<const double> v);
Json json_numbers(const Eigen::VectorXd& v);
/// Prints `j` compactly on one line.
void print_json(const Json& j);

/// Opens every store named (at least one); an analysis over several reads them as one database.
std::vector<store::Store> open_stores(const std::vector<std::string>& paths);
/// Where a basis learned from `inputs` is saved: `output` if given, else the first input store.
std::string basis_output(const std::vector<std::string>& inputs, const std::string& output);

/// A spectral BRDF grid named as STORE.h5:GRID, a grid exchange file (.spgrid) or a .spc (decoded by decode_spc);
/// `command` prefixes usage errors.
/// A spectral RGL .bsdf is evaluated at the cell centres on its own wavelengths (codec/rgl_eval.h); a grid made from a
/// .bsdf (spectral or RGB) carries the file's parameterisation (store::Grid::parameterisation).
/// With `uplift_onto`, an RGB MERL .binary or RGB .bsdf is accepted too, uplifted onto those bands as `specula uplift`
/// does by default (Appendix A under D65, default alpha, clamped); without, either is a UsageError saying so.
store::Grid load_grid(const std::string& spec, const std::string& command,
                      const std::optional<WavelengthGrid>& uplift_onto = std::nullopt);
/// The bands an RGB .binary is uplifted onto when nothing else decides them: 400-700 nm step 10, as `specula uplift`.
WavelengthGrid default_uplift_wavelengths();
/// Saves `grid` as STORE.h5:NAME (a transaction; --replace semantics from `replace`), a .spgrid file, or an RGB
/// MERL .binary (through the CIE 1931 CMFs under D65); returns a description of what was written.
std::string save_grid(const store::Grid& grid, const std::string& spec, bool replace, const std::string& command);

}  // namespace specula::app
