#pragma once
// What the subcommands share: provenance of the command line, illuminant and preview options,
// rendering a cube to sRGB, JSON output.
#include <CLI/CLI.hpp>
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "specula/core/colour.h"
#include "specula/store/cube.h"
#include "specula/store/store.h"

namespace specula::app {

using store::Cube;

/// The command line as typed, recorded as provenance.
const std::string& command_line();
/// Remembers argv for command_line().
void set_command_line(int argc, char** argv);

/// An SPD: a CIE name ("D65", "D50", "A", "E"), "D<CCT>" daylight (e.g. D75 = 7500 K), "blackbody:K", or a
/// CSV file "wavelength_nm,value" (header optional); resampled to grid. Throws UsageError/InputError.
Eigen::VectorXd load_illuminant(const std::string& spec, const WavelengthGrid& grid);

/// Options that turn spectra into an sRGB picture.
struct PreviewOptions {
  std::string illuminant = "D65";
  std::string exposure = "auto";
  std::string tone = "clip";
  bool no_desaturate = false;
  bool no_adapt = false;
};
/// Registers --exposure, --tone, --no-desaturate, --no-adapt (and --illuminant when asked) on `cmd`.
void add_preview_options(CLI::App* cmd, PreviewOptions& o, bool with_illuminant = true);

/// A rendered picture: 8-bit sRGB and the linear RGB behind it (3 values per pixel, row-major).
struct Picture {
  std::size_t width = 0, height = 0;
  std::vector<std::uint8_t> srgb8;
  std::vector<float> linear;
};
/// Renders `cube` as its units say (reflectance lit by the illuminant, radiance as is); masked pixels are
/// drawn dark red as the reference's figure 7.1 marks them. "auto" exposure maps the 99th percentile
/// luminance of valid pixels to 1 for radiance (0 EV for reflectance).
Picture render(const Cube& cube, const PreviewOptions& o);
/// XYZ rows of a cube's pixels (N x 3) under the preview options' illuminant.
RowMatrixX3f cube_xyz(const Cube& cube, const Eigen::VectorXd& illuminant, Eigen::Vector3d& white);

/// The error-map colour ramp (black, blue, magenta, orange, yellow, white) at t in [0, 1] (clamped).
std::array<std::uint8_t, 3> heat(double t);

/// Y (column 1) of xyz, one row per pixel of `cube`, at the cube's valid pixels.
std::vector<float> valid_luminance(const Eigen::Ref<const RowMatrixX3f>& xyz, const Cube& cube);
/// The q-quantile (0 <= q <= 1) of values, or 0 when there are none; reorders values.
double quantile(std::vector<float>& values, double q);
/// Parses --exposure: stops between -64 and 64, or std::nullopt for "auto"; throws UsageError otherwise.
std::optional<double> parse_exposure(const std::string& spec);

/// JSON string literal with escapes.
std::string json_string(std::string_view s);
/// JSON array of numbers (shortest round-trip formatting).
std::string json_array(std::span<const double> v);

/// Opens every store named (at least one); an analysis over several reads them as one database.
std::vector<store::Store> open_stores(const std::vector<std::string>& paths);
/// Where a basis learned from `inputs` is saved: `output` if given, else the first input store.
std::string basis_output(const std::vector<std::string>& inputs, const std::string& output);

/// A spectral BRDF grid named as STORE.h5:GRID or a grid exchange file (.spgrid); `command` prefixes usage errors.
/// With `uplift_onto`, an RGB MERL .binary is accepted too, uplifted onto those bands as `specula uplift` does by
/// default (Appendix A under D65, default alpha, clamped); without, a .binary is a UsageError saying so.
store::Grid load_grid(const std::string& spec, const std::string& command,
                      const std::optional<WavelengthGrid>& uplift_onto = std::nullopt);
/// The bands an RGB .binary is uplifted onto when nothing else decides them: 400-700 nm step 10, as `specula uplift`.
WavelengthGrid default_uplift_wavelengths();
/// Saves `grid` as STORE.h5:NAME (a transaction; --replace semantics from `replace`), a .spgrid file, or an RGB
/// MERL .binary (through the CIE 1931 CMFs under D65); returns a description of what was written.
std::string save_grid(const store::Grid& grid, const std::string& spec, bool replace, const std::string& command);

/// XYZ of a rendering to linear sRGB: its white (XYZ) adapted to D65 (Bradford) and mapped to luminance 1.
Eigen::Matrix3d rendering_to_linear_srgb(const Eigen::Vector3d& white);

}  // namespace specula::app
