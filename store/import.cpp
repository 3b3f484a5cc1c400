#include "specula/store/import.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <fstream>
#include <mutex>
#include <optional>
#include <variant>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/core/text.h"
#include "specula/store/detail/import_paths.h"
#include "specula/store/io/brdf_irregular.h"
#include "specula/store/io/csv.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/gdal.h"
#include "specula/store/io/mask.h"
#include "specula/store/io/mat.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/io/text_library.h"

namespace specula::store {
using namespace import_detail;
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

// NaN/Inf at valid pixels of the n = mask.size() spectra in `data`: counted, and those pixels cleared in `mask` when
// `mark` (mask: 1 = valid).
struct NanCount {
  std::uint64_t values = 0, pixels = 0;
  std::size_t first = SIZE_MAX, first_band = 0;
};
NanCount find_nan(std::span<const float> data, std::size_t bands, std::span<std::uint8_t> mask, bool mark) {
  NanCount c;
  for (std::size_t p = 0; p < mask.size(); ++p) {
    if (!mask[p]) continue;
    const float* s = data.data() + p * bands;
    bool bad = false;
    for (std::size_t b = 0; b < bands; ++b)
      if (!std::isfinite(s[b])) {
        ++c.values;
        if (c.first == SIZE_MAX) c.first = p, c.first_band = b;
        bad = true;
      }
    if (bad) {
      ++c.pixels;
      if (mark) mask[p] = 0;
    }
  }
  return c;
}

std::string nan_message(const std::string& src, const NanCount& c, std::size_t width, std::size_t row0,
                        const WavelengthGrid& wl, const char* scope) {
  return fmt::format(
      "{}: {} NaN/Inf values in {} pixels{} (first at row {}, column {}, band {} = {} nm); "
      "set the `nan` option to \"mask\" to keep the image with those pixels masked",
      src, c.values, c.pixels, scope, row0 + c.first / width, c.first % width, c.first_band,
      wl.empty() ? 0.0 : wl[c.first_band]);
}

// Applies the NaN/Inf policy: reject (one line naming the count and the first position) or mask.
void apply_nan_policy(Cube& c, NanPolicy policy, const std::string& src, std::vector<std::string>& notes) {
  std::vector<std::uint8_t> mask = c.mask.empty() ? std::vector<std::uint8_t>(c.height * c.width, 1) : c.mask;
  const NanCount n = find_nan(c.data, c.bands, mask, policy == NanPolicy::mask);
  if (n.values == 0) return;
  if (policy == NanPolicy::reject) throw InputError(nan_message(src, n, c.width, 0, c.wavelengths, ""));
  c.mask = std::move(mask);
  notes.push_back(fmt::format("{}: masked {} pixels holding NaN/Inf", src, n.pixels));
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
  if (std::filesystem::is_directory(p) || s.empty())
    s = std::filesystem::absolute(p).lexically_normal().filename().string();
  if (s.empty()) s = "image";
  const auto dot = s.find('.');
  if (dot != std::string::npos && dot > 0) s = s.substr(0, dot);
  for (char& ch : s)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '+')) ch = '_';
  return s;
}

struct Item {
  std::string format;
  std::vector<std::filesystem::path> files;
};

// What reading one item produced, waiting for its turn to be written.
struct Loaded {
  std::string name;
  std::variant<std::monostate, Cube, Collection, IrregularBrdf> object;
  std::vector<std::string> notes;
  bool stream_gdal = false;  // read while writing, by row strips
};

std::uint64_t file_bytes(const std::filesystem::path& p) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(p, ec);
  return ec ? 0 : n;
}

// PNG width x height from the IHDR, or 0.
std::uint64_t png_pixels(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  unsigned char h[24] = {};
  if (!in.read(reinterpret_cast<char*>(h), 24)) return 0;
  const auto be = [&](int at) { return std::uint64_t(h[at]) << 24 | h[at + 1] << 16 | h[at + 2] << 8 | h[at + 3]; };
  return be(16) * be(20);
}

// Bytes reading `item` takes at its peak, from the headers (file sizes when they cannot tell).
std::uint64_t estimate_bytes(const Item& item, const ImportOptions& o) {
  const std::filesystem::path& first = item.files.front();
  std::uint64_t floats = 0;  // decoded float32 bytes
  try {
    if (item.format == "gdal") return 3 * o.strip_bytes;
    if (item.format == "mat") return mat_decoded_bytes(first);
    if (item.format == "envi") {
      const std::filesystem::path h = lower(first.extension().string()) == ".hdr" ? first : envi_header_of(first);
      std::ifstream in(h, std::ios::binary);
      std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      const EnviHeader eh = parse_envi_header(text, h.string());
      floats = std::uint64_t(eh.samples) * eh.lines * eh.bands * sizeof(float);
    } else if (item.format == "png") {
      std::vector<std::filesystem::path> pngs;
      for (const auto& f : item.files) {
        if (std::filesystem::is_directory(f)) {
          for (const auto& e : sorted_entries(f))
            if (lower(e.path().extension().string()) == ".png") pngs.push_back(e.path());
        } else {
          pngs.push_back(f);
        }
      }
      for (const auto& f : pngs) floats += png_pixels(f) * (sizeof(float) + sizeof(std::uint16_t));
    }
  } catch (const Error&) {}
  if (floats == 0)
    for (const auto& f : item.files) floats += 4 * file_bytes(f);
  return o.wavelengths.empty() ? floats + floats / 4 : 2 * floats + floats / 4;
}

// A CSV table or a .mat spectral library as a collection on the target grid.
Collection read_table(const Item& item, const ImportOptions& o, bool mat_library) {
  const WavelengthGrid& target = o.wavelengths;
  const WavelengthGrid& source = o.source_wavelengths;
  const WavelengthGrid& given = source.empty() ? target : source;  // the grid of data without its own
  const std::filesystem::path& first = item.files.front();
  const std::string src = first.string();
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
  return col;
}

// A spectral library (USGS, ECOSTRESS, ENVI .sli) as a collection on its own grid (resampled only to the target's).
void read_library(const Item& item, const ImportOptions& o, Loaded& out) {
  const WavelengthGrid& target = o.wavelengths;
  const WavelengthGrid& source = o.source_wavelengths;
  const WavelengthGrid& given = source.empty() ? target : source;  // the grid of data without its own
  const std::filesystem::path& first = item.files.front();
  const std::string src = first.string();
  // Spectral libraries become collections on their own grid (resampled only to the target grid).
  TextLibrary lib;
  std::string label = src;
  if (item.format == "envi") {
    lib.collection = read_envi_library(first, o.honour_bbl, given);
  } else if (item.format == "ecostress") {
    lib = read_ecostress_spectra(item.files);
  } else {
    std::vector<std::filesystem::path> spectra, wl;
    for (const auto& f : item.files) (sniff_text_library(f) == "usgs-wavelengths" ? wl : spectra).push_back(f);
    if (wl.size() != 1 || spectra.empty())
      throw UsageError(
          fmt::format("{}: USGS splib07a spectra need exactly one Wavelengths file among the inputs "
                      "(found {}) and at least one spectrum (found {})",
                      src, wl.size(), spectra.size()));
    lib = read_usgs_spectra(spectra, wl.front());
    label = spectra.front().string();
  }
  Collection& col = lib.collection;
  out.notes = lib.notes;
  if (!target.empty() && !target.approx_equal(col.wavelengths)) {
    col.values = resample(col.values, col.size(), col.wavelengths, target, label);
    col.wavelengths = target;
  }
  if (!o.units.empty()) col.units = o.units;
  if (o.name.empty()) out.name = default_name(item.format == "usgs" ? std::filesystem::path(label) : first);
  out.object = std::move(col);
}

// An image (ENVI, .mat, PNG stack, spectral EXR): masked, NaN policy applied, resampled to the target grid.
Cube read_image_item(const Item& item, const ImportOptions& o, std::vector<std::string>& notes) {
  const WavelengthGrid& target = o.wavelengths;
  const WavelengthGrid& source = o.source_wavelengths;
  const WavelengthGrid& given = source.empty() ? target : source;  // the grid of data without its own
  const std::filesystem::path& first = item.files.front();
  const std::string src = first.string();
  Cube cube;
  if (item.format == "envi") {
    cube = read_envi(first, given, o.honour_bbl);
  } else if (item.format == "mat") {
    cube = read_mat(first, o.var, o.mask.empty() ? std::nullopt : std::optional<std::string>(o.mask), given);
  } else if (item.format == "png") {
    if (given.empty())
      throw UsageError(src +
                       ": a PNG band stack carries no wavelengths; give the `wavelengths` option FIRST:LAST:STEP");
    cube = read_png_stack(item.files, given);
  } else if (item.format == "exr") {
    cube = read_spectral_exr(first);
  } else {
    throw UsageError("format '" + item.format + "': use auto, envi, mat, png, exr, csv, brdf, usgs, ecostress or gdal");
  }
  if (!o.mask.empty() && item.format != "mat") apply_mask(cube, o.mask);
  if (!o.units.empty()) cube.units = o.units;
  apply_nan_policy(cube, o.nan, src, notes);
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
  return cube;
}

// Reads one item into memory: everything but writing (GDAL rasters are only named here).
Loaded read_item(const Item& item, const ImportOptions& o) {
  const WavelengthGrid& target = o.wavelengths;
  const std::filesystem::path& first = item.files.front();
  const std::string src = first.string();
  Loaded out;
  out.name = o.name.empty() ? default_name(first) : o.name;
  if (item.format == "gdal") {
    out.stream_gdal = true;
    return out;
  }
  // A .mat spectral library (2-D spectra + wavelength vector, the ISETCam layout) lands as a collection.
  const bool mat_library = item.format == "mat" && mat_kind(first, o.var) == MatKind::collection;
  if (item.format == "csv" || mat_library) {
    out.object = read_table(item, o, mat_library);
    return out;
  }
  if (item.format == "usgs" || item.format == "ecostress" || (item.format == "envi" && is_envi_library(first))) {
    read_library(item, o, out);
    return out;
  }
  if (item.format == "brdf") {
    // Scattered BRDF samples (pbrt-v2's irregular format), optionally resampled to the target grid.
    IrregularBrdf b = read_brdf_irregular(first);
    if (!target.empty() && !target.approx_equal(b.wavelengths)) {
      b.values = resample(b.values, b.size(), b.wavelengths, target, src);
      b.wavelengths = target;
    }
    out.object = std::move(b);
    return out;
  }
  out.object = read_image_item(item, o, out.notes);
  return out;
}

// Streams a GDAL raster into image `name` by row strips of whole storage chunks: masked, NaN policy, resampled.
std::string write_gdal(StoreWriter& writer, const std::string& name, const std::filesystem::path& path,
                       const ImportOptions& o, std::vector<std::string>& notes) {
  const std::string src = path.string();
  const WavelengthGrid& given = o.source_wavelengths.empty() ? o.wavelengths : o.source_wavelengths;
  GdalRaster r(path, given);
  const std::size_t h = r.height(), w = r.width(), nb = r.bands();
  const bool resampling = !o.wavelengths.empty() && !o.wavelengths.approx_equal(r.wavelengths());
  const WavelengthGrid& grid = resampling ? o.wavelengths : r.wavelengths();
  Eigen::MatrixXf to;
  if (resampling) to = resample_matrix(r.wavelengths(), grid, src).cast<float>();
  std::optional<Mask> mask_file;
  if (!o.mask.empty()) {
    mask_file = read_mask(o.mask);
    if (mask_file->width != w || mask_file->height != h)
      throw InputError(
          fmt::format("{}: mask is {}x{}, image is {}x{}", o.mask, mask_file->width, mask_file->height, w, h));
  }
  Provenance prov;
  prov.source_file = src;
  prov.importer = "gdal-" + r.driver();
  const std::string units = o.units.empty() ? "unknown" : o.units;
  const std::vector<double> fwhm = resampling ? std::vector<double>{} : r.fwhm();
  const std::size_t chunk = writer.create_image(name, h, w, grid, fwhm, units, prov);
  const std::uint64_t row_bytes = gdal_strip_bytes(w, std::max(nb, grid.size()), 1);
  std::size_t strip = std::max<std::uint64_t>(1, o.strip_bytes / row_bytes);
  if (strip >= chunk) strip -= strip % chunk;  // whole chunks when a strip holds one
  strip = std::min(strip, h);
  std::vector<float> spectra(strip * w * nb), out(resampling ? strip * w * grid.size() : 0);
  std::vector<std::uint8_t> mask(strip * w);
  std::uint64_t valid = 0, nan_pixels = 0;
  for (std::size_t y0 = 0; y0 < h; y0 += strip) {
    check_interrupt();
    const std::size_t n = std::min(strip, h - y0), px = n * w;
    const std::span<float> s(spectra.data(), px * nb);
    const std::span<std::uint8_t> m(mask.data(), px);
    r.read_rows(y0, n, s, m);
    if (mask_file)
      for (std::size_t p = 0; p < px; ++p)
        if (!mask_file->valid[y0 * w + p]) m[p] = 0;
    const NanCount bad = find_nan(s, nb, m, o.nan == NanPolicy::mask);
    if (bad.values && o.nan == NanPolicy::reject)
      throw InputError(
          nan_message(src, bad, w, y0, r.wavelengths(), fmt::format(" of rows {} to {}", y0, y0 + n - 1).c_str()));
    nan_pixels += bad.pixels;
    for (std::size_t p = 0; p < px; ++p)
      if (m[p])
        ++valid;
      else
        std::fill_n(s.data() + p * nb, nb, 0.0f);
    std::span<const float> values = s;
    if (resampling) {
      Eigen::Map<const RowMatrixXf> in(s.data(), Eigen::Index(px), Eigen::Index(nb));
      Eigen::Map<RowMatrixXf> res(out.data(), Eigen::Index(px), Eigen::Index(grid.size()));
      res.noalias() = in * to.transpose();
      values = std::span<const float>(out.data(), px * grid.size());
    }
    writer.write_image_rows(name, y0, n, values, m);
  }
  if (nan_pixels) notes.push_back(fmt::format("{}: masked {} pixels holding NaN/Inf", src, nan_pixels));
  return fmt::format("imported image {}: {}x{}, {}, {} valid pixels, units {}", name, h, w, grid.describe(), valid,
                     units);
}

// Adds what read_item produced to the transaction; returns the report line.
std::string write_item(StoreWriter& writer, const Item& item, Loaded& l, const ImportOptions& o) {
  if (l.stream_gdal) return write_gdal(writer, l.name, item.files.front(), o, l.notes);
  if (auto* col = std::get_if<Collection>(&l.object)) {
    writer.add_collection(l.name, *col);
    return fmt::format("imported collection {}: {} spectra, {}", l.name, col->size(), col->wavelengths.describe());
  }
  if (auto* b = std::get_if<IrregularBrdf>(&l.object)) {
    Provenance prov;
    prov.source_file = item.files.front().string();
    prov.importer = "brdf-irregular";
    writer.create_samples(l.name, b->wavelengths, o.units.empty() ? "1/sr" : o.units, prov);
    writer.append_samples(l.name, b->angles, b->values);
    return fmt::format("imported samples {}: {} scattered BRDF samples, {}", l.name, b->size(),
                       b->wavelengths.describe());
  }
  const Cube& cube = std::get<Cube>(l.object);
  writer.add_image(l.name, cube);
  const std::size_t valid =
      cube.mask.empty() ? cube.height * cube.width : std::size_t(std::count(cube.mask.begin(), cube.mask.end(), 1));
  return fmt::format("imported image {}: {}x{}, {}, {} valid pixels, units {}", l.name, cube.height, cube.width,
                     cube.wavelengths.describe(), valid, cube.units);
}

// Admits items in index order while at most `jobs` are in flight and their estimates fit the budget (one item is
// always admitted when none is in flight), and lets them write in index order. After a failure at item f, items
// above f stop at their next wait, so the error reported is the one a serial run meets first.
class Schedule {
 public:
  Schedule(unsigned jobs, std::uint64_t budget) : jobs_(std::max(1u, jobs)), budget_(budget) {}

  // Waits until item i may start reading; false when it should stop.
  bool admit(std::size_t i, std::uint64_t bytes) {
    std::unique_lock lock(m_);
    wait(lock, [&] {
      return i > failed_ || (next_admit_ == i && (in_flight_ == 0 || (in_flight_ < jobs_ && used_ + bytes <= budget_)));
    });
    if (i > failed_) return false;
    ++next_admit_;
    ++in_flight_;
    used_ += bytes;
    cv_.notify_all();
    return true;
  }
  // Waits until item i may write; false when it should stop.
  bool turn(std::size_t i) {
    std::unique_lock lock(m_);
    wait(lock, [&] { return i > failed_ || next_write_ == i; });
    return i <= failed_;
  }
  // Item i is done (written or failed): its memory is free and the next item may write.
  void done(std::size_t i, std::uint64_t bytes, bool ok) {
    std::lock_guard lock(m_);
    --in_flight_;
    used_ -= bytes;
    if (!ok) failed_ = std::min(failed_, i);
    if (ok && next_write_ == i) ++next_write_;
    cv_.notify_all();
  }

 private:
  template <class Pred>
  void wait(std::unique_lock<std::mutex>& lock, Pred pred) {
    while (!cv_.wait_for(lock, std::chrono::milliseconds(100), pred)) check_interrupt();
  }
  std::mutex m_;
  std::condition_variable cv_;
  unsigned jobs_;
  std::uint64_t budget_, used_ = 0;
  std::size_t in_flight_ = 0, next_admit_ = 0, next_write_ = 0, failed_ = SIZE_MAX;
};

}  // namespace
ImportReport import_files(StoreWriter& writer, const std::vector<std::filesystem::path>& inputs,
                          const ImportOptions& o) {
  ImportReport report;
  ImportInputs found = expand_import_inputs(inputs, o);
  report.skipped = found.skipped;
  if (o.strict && !found.skipped.empty())
    throw InputError(
        fmt::format("{} ({} file{} skipped in all); the `strict` option makes a skip an error: remove the "
                    "file, or import without `strict`",
                    found.skipped.front(), found.skipped.size(), found.skipped.size() == 1 ? "" : "s"));
  if (found.files.empty())
    throw InputError("no file to import among the inputs" +
                     (found.skipped.empty() ? std::string() : ": " + found.skipped.front()));
  std::vector<Item> items;
  for (const auto& in : found.files) {
    const std::string fmt_ = o.format == "auto" ? detect_import_format(in) : o.format;
    const bool loose_png = fmt_ == "png" && !std::filesystem::is_directory(in);
    const bool groups = loose_png || fmt_ == "usgs" || fmt_ == "ecostress";
    if (groups && !items.empty() && items.back().format == fmt_ &&
        (fmt_ != "png" || !std::filesystem::is_directory(items.back().files.back())))
      items.back().files.emplace_back(in);  // PNG files named together form one band stack; text spectra one collection
    else
      items.push_back({fmt_, {in}});
  }
  if (!o.name.empty() && items.size() > 1)
    throw UsageError(
        fmt::format("the `name` option names one object but the inputs make {}; leave it empty to name "
                    "them by file",
                    items.size()));

  const std::size_t n = items.size();
  std::vector<std::uint64_t> bytes(n);
  for (std::size_t i = 0; i < n; ++i) bytes[i] = estimate_bytes(items[i], o);
  std::vector<std::string> lines(n);
  std::vector<std::vector<std::string>> notes(n);
  std::vector<std::exception_ptr> errors(n);
  Schedule schedule(o.jobs, o.memory_budget);
  std::optional<Progress> progress;  // one bar over the files; a single file keeps the bar of its own writing
  if (n > 1) progress.emplace("importing", n);
  const auto one = [&](std::size_t i) {
    if (!schedule.admit(i, bytes[i])) return;
    bool ok = false;
    try {
      Loaded l = read_item(items[i], o);
      if (schedule.turn(i)) {
        lines[i] = write_item(writer, items[i], l, o);
        notes[i] = std::move(l.notes);
        ok = true;
      }
    } catch (...) {
      errors[i] = std::current_exception();
    }
    schedule.done(i, bytes[i], ok);
    if (ok && progress) progress->advance();
  };
  if (o.jobs <= 1 || n == 1) {
    for (std::size_t i = 0; i < n; ++i) one(i);  // each file's own parallel loops keep every thread
  } else {
    parallel_for(n, one);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (errors[i]) std::rethrow_exception(errors[i]);
    report.notes.insert(report.notes.end(), notes[i].begin(), notes[i].end());
    if (!lines[i].empty()) report.imported.push_back(lines[i]);
  }
  return report;
}

}  // namespace specula::store
