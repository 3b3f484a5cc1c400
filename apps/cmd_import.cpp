// specula import: ENVI, MATLAB, PNG stacks, spectral OpenEXR and CSV tables into a store, all files in one
// transaction (all or nothing), resampled to a target wavelength grid when asked.
#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <cmath>
#include <utility>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/store/io/brdf_irregular.h"
#include "specula/store/io/csv.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/mat.h"
#include "specula/store/io/mask.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/io/text_library.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct ImportOptions {
  std::vector<std::string> inputs;
  std::string output;
  std::string name;
  std::string wavelengths;
  std::string source_wavelengths;
  std::string mask;
  std::string var;  // empty: detected from the file (store/io/mat.h)
  std::string format = "auto";
  std::string nan = "reject";
  std::string compression = "deflate";
  std::string units;
  bool replace = false;
  bool keep_bad_bands = false;
};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

std::string detect_format(const std::filesystem::path& p) {
  if (std::filesystem::is_directory(p)) return "png";
  const std::string ext = lower(p.extension().string());
  if (ext == ".hdr" || ext == ".raw" || ext == ".img" || ext == ".dat" || ext == ".bsq" || ext == ".bil" || ext == ".bip" ||
      ext == ".sli")
    return "envi";  // an ENVI Spectral Library among them is told by its header (file type)
  if (ext == ".mat") return "mat";
  if (ext == ".png") return "png";
  if (ext == ".exr") return "exr";
  if (ext == ".csv") return "csv";
  if (ext == ".brdf") return "brdf";
  if (ext == ".txt") {
    const std::string kind = store::sniff_text_library(p);
    if (kind == "usgs" || kind == "usgs-wavelengths") return "usgs";
    if (kind == "ecostress") return "ecostress";
    throw UsageError(p.string() + ": a .txt that is neither a USGS splib07a spectrum (title \"splib07a Record=...\") "
                     "nor an ECOSTRESS spectrum (first line \"Name: ...\"); pass --format usgs|ecostress|csv");
  }
  throw UsageError(p.string() + ": cannot tell the format from the extension '" + ext +
                   "'; pass --format envi|mat|png|exr|csv|brdf|usgs|ecostress");
}

// Resamples every spectrum of `values` (count x from.size()) onto `to`, refusing extrapolation.
std::vector<float> resample(const std::vector<float>& values, std::size_t count, const WavelengthGrid& from,
                            const WavelengthGrid& to, const std::string& ctx) {
  const Eigen::MatrixXf r = resample_matrix(from, to, ctx).cast<float>();
  std::vector<float> out(count * to.size());
  Eigen::Map<const RowMatrixXf> in(values.data(), Eigen::Index(count), Eigen::Index(from.size()));
  Eigen::Map<RowMatrixXf> o(out.data(), Eigen::Index(count), Eigen::Index(to.size()));
  o.noalias() = in * r.transpose();
  return out;
}

// Applies the NaN/Inf policy: reject (one line naming the count and the first position) or mask.
void apply_nan_policy(Cube& c, const std::string& policy, const std::string& src) {
  std::uint64_t bad_values = 0, bad_pixels = 0;
  std::size_t first = SIZE_MAX, first_band = 0;
  const std::size_t px = c.height * c.width;
  std::vector<std::uint8_t> bad(px, 0);
  for (std::size_t p = 0; p < px; ++p) {
    if (!c.mask.empty() && !c.mask[p]) continue;
    const float* s = c.data.data() + p * c.bands;
    for (std::size_t b = 0; b < c.bands; ++b)
      if (!std::isfinite(s[b])) {
        ++bad_values;
        if (!bad[p]) ++bad_pixels;
        bad[p] = 1;
        if (first == SIZE_MAX) first = p, first_band = b;
      }
  }
  if (bad_values == 0) return;
  if (policy == "reject")
    throw InputError(fmt::format("{}: {} NaN/Inf values in {} pixels (first at row {}, column {}, band {} = {} nm); "
                                 "pass --nan mask to mask those pixels",
                                 src, bad_values, bad_pixels, first / c.width, first % c.width, first_band,
                                 c.wavelengths.empty() ? 0.0 : c.wavelengths[first_band]));
  if (c.mask.empty()) c.mask.assign(px, 1);
  for (std::size_t p = 0; p < px; ++p)
    if (bad[p]) c.mask[p] = 0;
  fmt::print(stderr, "{}: masked {} pixels holding NaN/Inf\n", src, bad_pixels);
}

void apply_mask(Cube& c, const std::string& path) {
  const store::Mask m = store::read_mask(path);
  if (m.width != c.width || m.height != c.height)
    throw InputError(fmt::format("{}: mask is {}x{}, image is {}x{}", path, m.width, m.height, c.width, c.height));
  if (c.mask.empty()) c.mask.assign(c.width * c.height, 1);
  for (std::size_t p = 0; p < c.width * c.height; ++p)
    if (!m.valid[p]) c.mask[p] = 0;
}

std::string default_name(const std::filesystem::path& p) {
  std::string s = p.filename().string();
  if (std::filesystem::is_directory(p) || s.empty()) s = std::filesystem::absolute(p).lexically_normal().filename().string();
  if (s.empty()) s = "image";
  const auto dot = s.find('.');
  if (dot != std::string::npos && dot > 0) s = s.substr(0, dot);
  for (char& ch : s)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '+')) ch = '_';
  return s;
}

void run_import(const ImportOptions& o) {
  const store::Compression compression = store::Compression::parse(o.compression);
  const WavelengthGrid target = o.wavelengths.empty() ? WavelengthGrid{} : WavelengthGrid::parse(o.wavelengths);
  const WavelengthGrid source = o.source_wavelengths.empty() ? WavelengthGrid{} : WavelengthGrid::parse(o.source_wavelengths);
  // The grid data without its own wavelengths is on: --source-wavelengths, else --wavelengths.
  const WavelengthGrid& given = source.empty() ? target : source;

  struct Item {
    std::string format;
    std::vector<std::filesystem::path> files;
  };
  std::vector<Item> items;
  for (const auto& in : o.inputs) {
    const std::string fmt_ = o.format == "auto" ? detect_format(in) : o.format;
    if ((fmt_ == "png" || fmt_ == "usgs" || fmt_ == "ecostress") && !items.empty() && items.back().format == fmt_)
      items.back().files.emplace_back(in);  // all PNGs form one band stack; text spectra one collection
    else
      items.push_back({fmt_, {in}});
  }
  if (!o.name.empty() && items.size() > 1)
    throw UsageError(fmt::format("--name names one object but the inputs make {}; drop --name to name them by file",
                                 items.size()));

  std::vector<std::string> report;  // printed only once everything has landed
  store::StoreWriter writer(o.output, {.compression = compression, .replace = o.replace, .command_line = command_line()});
  for (const auto& item : items) {
    const std::filesystem::path& first = item.files.front();
    const std::string src = first.string();
    const std::string name = o.name.empty() ? default_name(first) : o.name;
    // A .mat spectral library (2-D spectra + wavelength vector, the ISETCam layout) lands as a collection.
    const bool mat_library = item.format == "mat" && store::mat_kind(first, o.var) == store::MatKind::collection;
    if (item.format == "csv" || mat_library) {
      // The target grid is the table's own grid only for a table without a wavelength header.
      store::Collection col;
      if (mat_library) {
        col = store::read_mat_collection(first, o.var, given);
      } else {
        try {
          col = store::read_csv_collection(first, source);
        } catch (const InputError& no_grid) {
          if (!source.empty() || target.empty()) throw;
          try {
            col = store::read_csv_collection(first, target);
          } catch (const InputError&) {
            throw no_grid;
          }
        }
      }
      if (!target.empty() && !target.approx_equal(col.wavelengths)) {
        col.values = resample(col.values, col.size(), col.wavelengths, target, src);
        col.wavelengths = target;
      }
      if (!o.units.empty()) col.units = o.units;
      col.provenance.source_file = src;
      col.provenance.importer = item.format;
      writer.add_collection(name, col);
      report.push_back(fmt::format("imported collection {}: {} spectra, {}", name, col.size(), col.wavelengths.describe()));
      continue;
    }
    if (item.format == "usgs" || item.format == "ecostress" ||
        (item.format == "envi" && store::is_envi_library(first))) {
      // Spectral libraries become collections on their own grid (resampled only to --wavelengths).
      store::TextLibrary lib;
      std::string label = src;
      if (item.format == "envi") {
        lib.collection = store::read_envi_library(first, !o.keep_bad_bands, given);
      } else if (item.format == "ecostress") {
        lib = store::read_ecostress_spectra(item.files);
      } else {
        std::vector<std::filesystem::path> spectra, wl;
        for (const auto& f : item.files)
          (store::sniff_text_library(f) == "usgs-wavelengths" ? wl : spectra).push_back(f);
        if (wl.size() != 1 || spectra.empty())
          throw UsageError(fmt::format("{}: USGS splib07a spectra need exactly one Wavelengths file among the inputs "
                                       "(found {}) and at least one spectrum (found {})", src, wl.size(), spectra.size()));
        lib = store::read_usgs_spectra(spectra, wl.front());
        label = spectra.front().string();
      }
      store::Collection& col = lib.collection;
      for (const auto& note : lib.notes) fmt::print(stderr, "{}\n", note);
      if (!target.empty() && !target.approx_equal(col.wavelengths)) {
        col.values = resample(col.values, col.size(), col.wavelengths, target, label);
        col.wavelengths = target;
      }
      if (!o.units.empty()) col.units = o.units;
      const std::string lib_name =
          o.name.empty() ? default_name(item.format == "usgs" ? std::filesystem::path(label) : first) : o.name;
      writer.add_collection(lib_name, col);
      report.push_back(fmt::format("imported collection {}: {} spectra, {}", lib_name, col.size(), col.wavelengths.describe()));
      continue;
    }
    if (item.format == "brdf") {
      // Scattered BRDF samples (pbrt-v2's irregular format), optionally resampled to --wavelengths.
      store::IrregularBrdf b = store::read_brdf_irregular(first);
      if (!target.empty() && !target.approx_equal(b.wavelengths)) {
        b.values = resample(b.values, b.size(), b.wavelengths, target, src);
        b.wavelengths = target;
      }
      store::Provenance prov;
      prov.source_file = src;
      prov.importer = "brdf-irregular";
      writer.create_samples(name, b.wavelengths, o.units.empty() ? "1/sr" : o.units, prov);
      writer.append_samples(name, b.angles, b.values);
      report.push_back(fmt::format("imported samples {}: {} scattered BRDF samples, {}", name, b.size(), b.wavelengths.describe()));
      continue;
    }
    store::Cube cube;
    if (item.format == "envi") {
      cube = store::read_envi(first, given, !o.keep_bad_bands);
    } else if (item.format == "mat") {
      cube = store::read_mat(first, o.var, o.mask.empty() ? std::nullopt : std::optional<std::string>(o.mask), given);
    } else if (item.format == "png") {
      if (given.empty())
        throw UsageError(src + ": a PNG band stack carries no wavelengths; pass --wavelengths FIRST:LAST:STEP");
      cube = store::read_png_stack(item.files, given);
    } else if (item.format == "exr") {
      cube = store::read_spectral_exr(first);
    } else {
      throw UsageError("--format '" + item.format + "': use auto, envi, mat, png, exr, csv, usgs or ecostress");
    }
    if (!o.mask.empty() && item.format != "mat") apply_mask(cube, o.mask);
    if (!o.units.empty()) cube.units = o.units;
    apply_nan_policy(cube, o.nan, src);
    if (!target.empty() && !target.approx_equal(cube.wavelengths)) {
      // Masked pixels may hold anything; zero them so resampling cannot spread NaN.
      if (!cube.mask.empty())
        for (std::size_t p = 0; p < cube.mask.size(); ++p)
          if (!cube.mask[p]) std::fill_n(cube.data.begin() + std::ptrdiff_t(p * cube.bands), cube.bands, 0.0f);
      cube.data = resample(cube.data, cube.height * cube.width, cube.wavelengths, target, src);
      cube.wavelengths = target;
      cube.bands = target.size();
      cube.fwhm.clear();
    }
    cube.provenance.source_file = src;
    if (cube.provenance.importer.empty()) cube.provenance.importer = item.format;
    writer.add_image(name, cube);
    std::size_t valid = cube.mask.empty() ? cube.height * cube.width
                                          : std::size_t(std::count(cube.mask.begin(), cube.mask.end(), 1));
    report.push_back(fmt::format("imported image {}: {}x{}, {}, {} valid pixels, units {}", name, cube.height, cube.width,
               cube.wavelengths.describe(), valid, cube.units));
  }
  writer.commit();
  for (const auto& line : report) fmt::print("{}\n", line);
}

}  // namespace

void setup_import(CLI::App& app) {
  auto o = std::make_shared<ImportOptions>();
  auto* cmd = app.add_subcommand("import", "Import spectral images (ENVI, .mat, PNG stack, spectral EXR) or CSV tables into a store");
  cmd->add_option("inputs", o->inputs, "Input files (all PNGs together form one band stack; a directory of PNGs too)")
      ->required();
  cmd->add_option("-o,--output", o->output, "Store to create or add to")->required();
  cmd->add_option("--name", o->name, "Object name (default: the file name without extension)");
  cmd->add_option("--wavelengths", o->wavelengths,
                  "Target grid FIRST:LAST:STEP or a comma list; data is resampled linearly onto it (no extrapolation). "
                  "Also the data's own grid when it carries none (PNG stacks)");
  cmd->add_option("--source-wavelengths", o->source_wavelengths, "The data's own grid when it carries none and --wavelengths resamples");
  cmd->add_option("--mask", o->mask, "Mask: a PNG or a one-band ENVI image (nonzero = valid), or for .mat the name of a mask variable");
  cmd->add_option("--var", o->var, "Cube or spectra variable in a .mat file (default: detected, e.g. ref, rad, cube, Y, data)");
  cmd->add_option("--format", o->format, "auto, envi, mat, png, exr, csv, usgs (splib07a ASCII) or ecostress")
      ->check(CLI::IsMember({"auto", "envi", "mat", "png", "exr", "csv", "usgs", "ecostress"}))
      ->capture_default_str();
  cmd->add_option("--nan", o->nan, "NaN/Inf in valid pixels: reject (default) or mask")
      ->check(CLI::IsMember({"reject", "mask"}))
      ->capture_default_str();
  cmd->add_option("--compression", o->compression, "none, deflate or deflate:LEVEL (shuffle + deflate)")->capture_default_str();
  cmd->add_option("--units", o->units, "Override the units: reflectance, radiance, counts, ...");
  cmd->add_flag("--replace", o->replace, "Replace objects of the same name");
  cmd->add_flag("--keep-bad-bands", o->keep_bad_bands, "Keep the bands an ENVI header's bbl marks bad (dropped by default)");
  cmd->callback([o] {
    try {
      run_import(*o);
    } catch (const InputError& e) {  // the importers name their parameter; here it is a flag
      std::string m = e.what();
      for (const auto& [param, flag] : {std::pair<std::string, std::string>{"the `wavelengths` option", "--wavelengths"},
                                        {"the `var` option", "--var"},
                                        {"pass honour_bbl = false", "pass --keep-bad-bands"}})
        for (std::size_t at; (at = m.find(param)) != std::string::npos;) m.replace(at, param.size(), flag);
      throw InputError(m);
    }
  });
}

}  // namespace specula::app
