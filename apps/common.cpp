#include "apps/common.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "specula/codec/merl.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/uplift.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula::app {
namespace {
std::string g_command_line;

bool parse_double(const std::string& s, double& v) {
  try {
    std::size_t pos = 0;
    v = std::stod(s, &pos);
    return pos == s.size();
  } catch (...) {
    return false;
  }
}
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

Eigen::VectorXd load_illuminant(const std::string& spec, const WavelengthGrid& grid) {
  if (spec == "D65" || spec == "D50" || spec == "A" || spec == "E") return illuminant(spec, grid);
  double v = 0;
  if (spec.size() > 1 && (spec[0] == 'D' || spec[0] == 'd') && parse_double(spec.substr(1), v))
    return daylight(v * 100.0, grid);
  if (spec.rfind("blackbody:", 0) == 0 && parse_double(spec.substr(10), v)) {
    if (!(v >= 500 && v <= 50000)) throw UsageError("illuminant '" + spec + "': temperature must be 500-50000 K");
    return blackbody(v, grid);
  }
  if (!std::filesystem::exists(spec))
    throw UsageError("illuminant '" + spec +
                     "' is neither D65, D50, A, E, D<CCT/100> (e.g. D75), blackbody:<K> nor an existing SPD file");
  std::ifstream in(spec);
  std::vector<double> nm, val;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ';', ',');
    const auto comma = line.find(',');
    double a = 0, b = 0;
    if (comma == std::string::npos || !parse_double(line.substr(0, comma), a) || !parse_double(line.substr(comma + 1), b)) {
      if (nm.empty()) continue;  // header
      throw InputError(spec + ":" + std::to_string(lineno) + ": expected 'wavelength_nm,value'");
    }
    if (!std::isfinite(b)) throw InputError(spec + ":" + std::to_string(lineno) + ": value is not finite");
    nm.push_back(a);
    val.push_back(b);
  }
  if (nm.size() < 2) throw InputError(spec + ": an SPD needs at least two 'wavelength_nm,value' rows");
  const WavelengthGrid src(nm, spec);
  return resample_matrix(src, grid, spec) * Eigen::Map<const Eigen::VectorXd>(val.data(), Eigen::Index(val.size()));
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

RowMatrixX3f cube_xyz(const Cube& cube, const Eigen::VectorXd& illum, Eigen::Vector3d& white) {
  const SpectrumKind kind = cube.units == "reflectance" ? SpectrumKind::reflectance : SpectrumKind::radiance;
  const SpectrumToXyz to_xyz(cube.wavelengths, kind, illum);
  white = to_xyz.white();
  const Eigen::Index n = Eigen::Index(cube.height * cube.width);
  RowMatrixX3f xyz(n, 3);
  to_xyz.apply(Eigen::Map<const RowMatrixXf>(cube.data.data(), n, Eigen::Index(cube.bands)), xyz);
  return xyz;
}

Picture render(const Cube& cube, const PreviewOptions& o) {
  const Eigen::VectorXd illum = load_illuminant(o.illuminant, cube.wavelengths);
  Eigen::Vector3d white;
  RowMatrixX3f xyz = cube_xyz(cube, illum, white);
  DisplayOptions d;
  d.tone = o.tone == "reinhard" ? ToneMap::reinhard : ToneMap::clip;
  d.desaturate = !o.no_desaturate;
  d.adapt_to_d65 = !o.no_adapt;
  if (const auto stops = parse_exposure(o.exposure)) {
    d.exposure_stops = *stops;
  } else if (cube.units != "reflectance") {
    std::vector<float> y = valid_luminance(xyz, cube);
    const double white = quantile(y, 0.99);
    if (white > 0) d.exposure_stops = -std::log2(white);
  }
  Picture p;
  p.width = cube.width;
  p.height = cube.height;
  p.srgb8.resize(3 * std::size_t(xyz.rows()));
  RowMatrixX3f lin(xyz.rows(), 3);
  xyz_to_display(xyz, white, d, lin, p.srgb8);
  p.linear.assign(lin.data(), lin.data() + lin.size());
  if (!cube.mask.empty())
    for (std::size_t i = 0; i < cube.mask.size(); ++i)
      if (!cube.mask[i]) {
        p.srgb8[3 * i] = std::uint8_t(std::min(255, 96 + p.srgb8[3 * i] / 2));
        p.srgb8[3 * i + 1] = std::uint8_t(p.srgb8[3 * i + 1] / 4);
        p.srgb8[3 * i + 2] = std::uint8_t(p.srgb8[3 * i + 2] / 4);
      }
  return p;
}

std::vector<float> valid_luminance(const Eigen::Ref<const RowMatrixX3f>& xyz, const Cube& cube) {
  std::vector<float> y;
  y.reserve(std::size_t(xyz.rows()));
  for (Eigen::Index i = 0; i < xyz.rows(); ++i)
    if (cube.valid(std::size_t(i) / cube.width, std::size_t(i) % cube.width)) y.push_back(xyz(i, 1));
  return y;
}

double quantile(std::vector<float>& values, double q) {
  if (values.empty()) return 0.0;
  const auto k = values.begin() + std::ptrdiff_t(double(values.size() - 1) * std::clamp(q, 0.0, 1.0));
  std::nth_element(values.begin(), k, values.end());
  return double(*k);
}

std::optional<double> parse_exposure(const std::string& spec) {
  if (spec == "auto") return std::nullopt;
  double v = 0;
  if (!parse_double(spec, v) || !(std::abs(v) <= 64))
    throw UsageError("--exposure '" + spec + "': give stops between -64 and 64, or auto");
  return v;
}

std::array<std::uint8_t, 3> heat(double t) {
  static const double stops[6][3] = {{0, 0, 0}, {30, 30, 140}, {150, 40, 150}, {240, 100, 40}, {250, 220, 60}, {255, 255, 255}};
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 5.0;
  const int i = std::min(4, int(t));
  const double f = t - i;
  std::array<std::uint8_t, 3> c{};
  for (int k = 0; k < 3; ++k) c[std::size_t(k)] = std::uint8_t(std::lround(stops[i][k] * (1 - f) + stops[i + 1][k] * f));
  return c;
}

std::string json_string(std::string_view s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) out += fmt::format("\\u{:04x}", int(c));
        else out += c;
    }
  }
  return out + "\"";
}

std::string json_array(std::span<const double> v) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? "," : "") + (std::isfinite(v[i]) ? fmt::format("{}", v[i]) : "null");
  return out + "]";
}

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
  const auto colon = spec.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == spec.size()) return std::nullopt;
  const std::string file = spec.substr(0, colon);
  if (std::filesystem::exists(spec)) return std::nullopt;
  if (std::filesystem::is_regular_file(file) || (writing && std::filesystem::path(file).extension() == ".h5"))
    return std::pair{file, spec.substr(colon + 1)};
  return std::nullopt;
}
}  // namespace

store::Grid load_grid(const std::string& spec, const std::string& command, const std::optional<WavelengthGrid>& uplift_onto) {
  if (const auto s = store_spec(spec, false)) return store::Store::open(s->first).read_grid(s->second);
  const std::filesystem::path in(spec);
  if (in.extension() == ".h5")
    throw UsageError(command + ": " + spec + " is a store; name the grid as " + spec + ":GRID (see `specula ls " + spec + "`)");
  if (in.extension() == ".binary") {
    if (!uplift_onto)
      throw UsageError(command + ": " + spec + " is an RGB MERL file; make a spectral grid of it with `specula uplift` first");
    const codec::Uplift uplift(codec::rgb_weights(*uplift_onto, illuminant("D65", *uplift_onto)), codec::kDefaultUpliftAlpha);
    store::Grid g = codec::uplift_merl(codec::read_merl(in), *uplift_onto, uplift, codec::UpliftMethod::clamp);
    g.provenance.source_file = spec;
    g.provenance.importer = "uplift-clamp";
    return g;
  }
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
    return "RGB MERL file " + spec + (rgb.clamped ? " (" + std::to_string(rgb.clamped) + " out-of-gamut values clamped)" : "");
  }
  if (out.extension() == ".h5")
    throw UsageError(command + ": name the grid to write as " + spec + ":NAME");
  if (out.extension() != ".spgrid")
    throw UsageError(command + ": " + spec + ": write STORE.h5:NAME, a .spgrid exchange file or an RGB .binary");
  codec::write_grid_file(out, grid);
  return "spectral grid file " + spec;
}

Eigen::Matrix3d rendering_to_linear_srgb(const Eigen::Vector3d& white) {
  const Eigen::Vector3d d65(0.95047, 1.0, 1.08883);
  return xyz_to_linear_srgb() * bradford_adaptation(white / white.y(), d65) / white.y();
}

}  // namespace specula::app
