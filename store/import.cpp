#include "specula/store/import.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <optional>

#include "specula/core/error.h"
#include "specula/core/text.h"
#include "specula/store/io/brdf_irregular.h"
#include "specula/store/io/csv.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/mask.h"
#include "specula/store/io/mat.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/io/text_library.h"

namespace specula::store {
namespace {

using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

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
void apply_nan_policy(Cube& c, NanPolicy policy, const std::string& src, std::vector<std::string>& notes) {
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
  if (policy == NanPolicy::reject)
    throw InputError(fmt::format("{}: {} NaN/Inf values in {} pixels (first at row {}, column {}, band {} = {} nm); "
                                 "set the `nan` option to \"mask\" to keep the image with those pixels masked",
                                 src, bad_values, bad_pixels, first / c.width, first % c.width, first_band,
                                 c.wavelengths.empty() ? 0.0 : c.wavelengths[first_band]));
  if (c.mask.empty()) c.mask.assign(px, 1);
  for (std::size_t p = 0; p < px; ++p)
    if (bad[p]) c.mask[p] = 0;
  notes.push_back(fmt::format("{}: masked {} pixels holding NaN/Inf", src, bad_pixels));
}

void apply_mask(Cube& c, const std::string& path) {
  const Mask m = read_mask(path);
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

}  // namespace

std::string detect_import_format(const std::filesystem::path& p) {
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
    const std::string kind = sniff_text_library(p);
    if (kind == "usgs" || kind == "usgs-wavelengths") return "usgs";
    if (kind == "ecostress") return "ecostress";
    throw UsageError(p.string() + ": a .txt that is neither a USGS splib07a spectrum (title \"splib07a Record=...\") "
                     "nor an ECOSTRESS spectrum (first line \"Name: ...\"); give the `format` option (usgs, ecostress or csv)");
  }
  throw UsageError(p.string() + ": cannot tell the format from the extension '" + ext +
                   "'; give the `format` option (envi, mat, png, exr, csv, brdf, usgs or ecostress)");
}

ImportReport import_files(StoreWriter& writer, const std::vector<std::filesystem::path>& inputs,
                          const ImportOptions& o) {
  const WavelengthGrid& target = o.wavelengths;
  const WavelengthGrid& source = o.source_wavelengths;
  // The grid data without its own wavelengths is on: source_wavelengths, else wavelengths.
  const WavelengthGrid& given = source.empty() ? target : source;
  ImportReport report;
  struct Item {
    std::string format;
    std::vector<std::filesystem::path> files;
  };
  std::vector<Item> items;
  for (const auto& in : inputs) {
    const std::string fmt_ = o.format == "auto" ? detect_import_format(in) : o.format;
    if ((fmt_ == "png" || fmt_ == "usgs" || fmt_ == "ecostress") && !items.empty() && items.back().format == fmt_)
      items.back().files.emplace_back(in);  // all PNGs form one band stack; text spectra one collection
    else
      items.push_back({fmt_, {in}});
  }
  if (!o.name.empty() && items.size() > 1)
    throw UsageError(fmt::format("the `name` option names one object but the inputs make {}; leave it empty to name "
                                 "them by file", items.size()));

  for (const auto& item : items) {
    const std::filesystem::path& first = item.files.front();
    const std::string src = first.string();
    const std::string name = o.name.empty() ? default_name(first) : o.name;
    // A .mat spectral library (2-D spectra + wavelength vector, the ISETCam layout) lands as a collection.
    const bool mat_library = item.format == "mat" && mat_kind(first, o.var) == MatKind::collection;
    if (item.format == "csv" || mat_library) {
      // The target grid is the table's own grid only for a table without a wavelength header.
      Collection col;
      if (mat_library) {
        col = read_mat_collection(first, o.var, given);
      } else {
        try {
          col = read_csv_collection(first, source);
        } catch (const InputError& no_grid) {
          if (!source.empty() || target.empty()) throw;
          try {
            col = read_csv_collection(first, target);
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
      report.imported.push_back(fmt::format("imported collection {}: {} spectra, {}", name, col.size(), col.wavelengths.describe()));
      continue;
    }
    if (item.format == "usgs" || item.format == "ecostress" ||
        (item.format == "envi" && is_envi_library(first))) {
      // Spectral libraries become collections on their own grid (resampled only to the target grid).
      TextLibrary lib;
      std::string label = src;
      if (item.format == "envi") {
        lib.collection = read_envi_library(first, o.honour_bbl, given);
      } else if (item.format == "ecostress") {
        lib = read_ecostress_spectra(item.files);
      } else {
        std::vector<std::filesystem::path> spectra, wl;
        for (const auto& f : item.files)
          (sniff_text_library(f) == "usgs-wavelengths" ? wl : spectra).push_back(f);
        if (wl.size() != 1 || spectra.empty())
          throw UsageError(fmt::format("{}: USGS splib07a spectra need exactly one Wavelengths file among the inputs "
                                       "(found {}) and at least one spectrum (found {})", src, wl.size(), spectra.size()));
        lib = read_usgs_spectra(spectra, wl.front());
        label = spectra.front().string();
      }
      Collection& col = lib.collection;
      report.notes.insert(report.notes.end(), lib.notes.begin(), lib.notes.end());
      if (!target.empty() && !target.approx_equal(col.wavelengths)) {
        col.values = resample(col.values, col.size(), col.wavelengths, target, label);
        col.wavelengths = target;
      }
      if (!o.units.empty()) col.units = o.units;
      const std::string lib_name =
          o.name.empty() ? default_name(item.format == "usgs" ? std::filesystem::path(label) : first) : o.name;
      writer.add_collection(lib_name, col);
      report.imported.push_back(fmt::format("imported collection {}: {} spectra, {}", lib_name, col.size(), col.wavelengths.describe()));
      continue;
    }
    if (item.format == "brdf") {
      // Scattered BRDF samples (pbrt-v2's irregular format), optionally resampled to the target grid.
      IrregularBrdf b = read_brdf_irregular(first);
      if (!target.empty() && !target.approx_equal(b.wavelengths)) {
        b.values = resample(b.values, b.size(), b.wavelengths, target, src);
        b.wavelengths = target;
      }
      Provenance prov;
      prov.source_file = src;
      prov.importer = "brdf-irregular";
      writer.create_samples(name, b.wavelengths, o.units.empty() ? "1/sr" : o.units, prov);
      writer.append_samples(name, b.angles, b.values);
      report.imported.push_back(fmt::format("imported samples {}: {} scattered BRDF samples, {}", name, b.size(), b.wavelengths.describe()));
      continue;
    }
    Cube cube;
    if (item.format == "envi") {
      cube = read_envi(first, given, o.honour_bbl);
    } else if (item.format == "mat") {
      cube = read_mat(first, o.var, o.mask.empty() ? std::nullopt : std::optional<std::string>(o.mask), given);
    } else if (item.format == "png") {
      if (given.empty())
        throw UsageError(src + ": a PNG band stack carries no wavelengths; give the `wavelengths` option FIRST:LAST:STEP");
      cube = read_png_stack(item.files, given);
    } else if (item.format == "exr") {
      cube = read_spectral_exr(first);
    } else {
      throw UsageError("format '" + item.format + "': use auto, envi, mat, png, exr, csv, brdf, usgs or ecostress");
    }
    if (!o.mask.empty() && item.format != "mat") apply_mask(cube, o.mask);
    if (!o.units.empty()) cube.units = o.units;
    apply_nan_policy(cube, o.nan, src, report.notes);
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
    report.imported.push_back(fmt::format("imported image {}: {}x{}, {}, {} valid pixels, units {}", name, cube.height, cube.width,
               cube.wavelengths.describe(), valid, cube.units));
  }
  return report;
}

}  // namespace specula::store
