#include "entries.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include <zlib.h>

#include "specula/acquire/filters.h"
#include "specula/codec/merl.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/spc.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/error.h"
#include "specula/store/io/csv.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/gdal.h"
#include "specula/store/io/mask.h"
#include "specula/store/io/mat.h"
#include "specula/store/io/nbrdf.h"
#include "specula/store/io/text_library.h"

namespace specula::fuzz {
namespace {

namespace fs = std::filesystem;

void check(bool ok, const char* what) {
  if (!ok) throw std::logic_error(std::string("fuzz invariant broken: ") + what);
}

// This process's scratch directory, made once and removed at exit.
const fs::path& scratch() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("specula-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(fs::temp_directory_path() / ("specula-fuzz-" + std::to_string(::getpid())), ec);
    });
    return d;
  }();
  return dir;
}

std::string_view text_of(std::span<const std::uint8_t> input) {
  return {reinterpret_cast<const char*>(input.data()), input.size()};
}

std::vector<std::string_view> split_files(std::string_view all) {
  std::vector<std::string_view> parts;
  for (std::size_t at; (at = all.find(kFileSeparator)) != std::string_view::npos;) {
    parts.push_back(all.substr(0, at));
    all.remove_prefix(at + kFileSeparator.size());
  }
  parts.push_back(all);
  return parts;
}

fs::path write(const std::string& name, std::string_view bytes) {
  const fs::path p = scratch() / name;
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("fuzz: cannot write " + p.string());
  return p;
}

// Runs read(); a specula::Error must be one line containing `named` (the file, or the directory of the files).
template <typename F>
void expect_clean(F&& read, std::string_view named) {
  try {
    read();
  } catch (const Error& e) {
    const std::string what = e.what();
    if (what.find_first_of("\n\r") != std::string::npos || what.find(named) == std::string::npos)
      throw std::logic_error("fuzz: the error message is not one line naming the file: " + what);
    throw;
  }
}

void check_grid(const WavelengthGrid& g, std::size_t bands) {
  check(g.size() == bands, "one wavelength per band");
  for (std::size_t i = 0; i < g.size(); ++i) check(std::isfinite(g[i]) && g[i] > 0, "finite positive wavelengths");
  for (std::size_t i = 1; i < g.size(); ++i) check(g[i] > g[i - 1], "ascending wavelengths");
}

void check_cube(const store::Cube& c) {
  check(c.height > 0 && c.width > 0 && c.bands > 0, "non-empty cube");
  check(c.data.size() == c.height * c.width * c.bands, "cube data size");
  check(c.mask.empty() || c.mask.size() == c.height * c.width, "mask size");
  check(c.fwhm.empty() || c.fwhm.size() == c.bands, "one fwhm per band");
  check_grid(c.wavelengths, c.bands);
}

void check_collection(const store::Collection& c) {
  check(c.size() > 0 && c.bands() > 0, "non-empty collection");
  check(c.values.size() == c.size() * c.bands(), "collection values size");
  check_grid(c.wavelengths, c.bands());
}

// The rest of `input` after its mode byte: `head` bytes as given, then the bytes after them repeated to `size`.
std::string expand(std::span<const std::uint8_t> input, std::size_t head, std::uint64_t size) {
  const std::string_view rest = text_of(input).substr(1);
  std::string out(rest.substr(0, std::min(head, rest.size())));
  const std::string_view pattern = rest.size() > head ? rest.substr(head) : std::string_view("\xff", 1);
  out.reserve(size);
  while (out.size() < size) out.append(pattern.substr(0, std::min<std::uint64_t>(pattern.size(), size - out.size())));
  out.resize(size);
  return out;
}

void check_brdf_grid(const store::Grid& g) {
  check(g.bands() > 0 && g.brdf.size() == g.bands() * brdf::kMerlCells, "bands x 90 x 90 x 180 values");
  check(std::isfinite(g.scale) && g.scale > 0, "finite positive scale");
  check_grid(g.wavelengths, g.bands());
  for (const float v : g.brdf) check(std::isfinite(v), "finite values");
}

}  // namespace

void envi_header(std::span<const std::uint8_t> input) {
  expect_clean(
      [&] {
        const store::EnviHeader h = store::parse_envi_header(text_of(input), "fuzz.hdr");
        check(h.samples > 0 && h.lines > 0 && h.bands > 0, "positive dimensions");
        check(h.data_type == 1 || h.data_type == 2 || h.data_type == 3 || h.data_type == 4 || h.data_type == 5 ||
                  h.data_type == 12,
              "supported data type");
        check(h.byte_order == 0 || h.byte_order == 1, "byte order 0 or 1");
        check(h.wavelength.empty() || h.wavelength.size() == h.bands, "one wavelength per band");
        check(h.fwhm.empty() || h.fwhm.size() == h.bands, "one fwhm per band");
        check(h.band_names.empty() || h.band_names.size() == h.bands, "one name per band");
        std::uint64_t bytes = 0;
        const bool overflow = __builtin_mul_overflow(std::uint64_t{h.samples}, std::uint64_t{h.lines}, &bytes) ||
                              __builtin_mul_overflow(bytes, std::uint64_t{h.bands}, &bytes) ||
                              __builtin_mul_overflow(bytes, std::uint64_t{8}, &bytes);
        check(!overflow && bytes <= (std::uint64_t{1} << 43), "size limit");
      },
      "fuzz.hdr");
}

void envi(std::span<const std::uint8_t> input) {
  const auto parts = split_files(text_of(input));
  const fs::path hdr = write("envi.hdr", parts[0]);
  write("envi.sli", parts.size() > 1 ? parts[1] : std::string_view());
  const std::string dir = scratch().string();
  if (store::is_envi_library(hdr)) {
    for (const bool honour_bbl : {true, false})
      expect_clean([&] { check_collection(store::read_envi_library(hdr, honour_bbl)); }, dir);
  } else {
    for (const bool honour_bbl : {true, false})
      expect_clean([&] { check_cube(store::read_envi(hdr, {}, honour_bbl)); }, dir);
  }
}

void mat(std::span<const std::uint8_t> input) {
  const fs::path p = write("input.mat", text_of(input));
  expect_clean(
      [&] {
        if (store::mat_kind(p) == store::MatKind::collection)
          check_collection(store::read_mat_collection(p, "", {}));
        else
          check_cube(store::read_mat(p, "", std::nullopt, {}));
      },
      p.string());
}

void mask(std::span<const std::uint8_t> input) {
  const std::string_view all = text_of(input);
  fs::path p;
  if (all.starts_with("\x89PNG")) {
    std::error_code ec;
    fs::remove(scratch() / "mask.hdr", ec);
    p = write("mask.png", all);
  } else {
    const auto parts = split_files(all);
    write("mask.hdr", parts[0]);
    p = write("mask.img", parts.size() > 1 ? parts[1] : std::string_view());
  }
  expect_clean(
      [&] {
        const store::Mask m = store::read_mask(p);
        check(m.width > 0 && m.height > 0 && m.valid.size() == m.width * m.height, "mask size");
        for (const std::uint8_t v : m.valid) check(v == 0 || v == 1, "mask holds 0 or 1");
      },
      scratch().string());
}

void text_library(std::span<const std::uint8_t> input) {
  const auto parts = split_files(text_of(input));
  std::vector<fs::path> files;
  for (std::size_t i = 0; i < parts.size(); ++i)
    files.push_back(write("library" + std::to_string(i) + ".txt", parts[i]));
  expect_clean(
      [&] {
        const bool ecostress = store::sniff_text_library(files[0]) == "ecostress";
        if (!ecostress && files.size() < 2) return;  // USGS needs a wavelengths file and a spectrum
        const store::TextLibrary lib = ecostress ? store::read_ecostress_spectra(files)
                                                 : store::read_usgs_spectra(std::span(files).subspan(1), files[0]);
        check_collection(lib.collection);
        for (const float v : lib.collection.values) check(std::isfinite(v), "finite values");
      },
      scratch().string());
}

void csv(std::span<const std::uint8_t> input) {
  const fs::path p = write("input.csv", text_of(input));
  expect_clean([&] { check_collection(store::read_csv_collection(p)); }, p.string());
}

void gdal(std::span<const std::uint8_t> input) {
  const fs::path p = write("input.tif", text_of(input));
  expect_clean(
      [&] {
        store::GdalRaster r(p, WavelengthGrid({450, 550, 650}));
        check_grid(r.wavelengths(), r.bands());
        check(r.height() > 0 && r.width() > 0, "non-empty raster");
        check(r.fwhm().empty() || r.fwhm().size() == r.bands(), "one fwhm per band");
        constexpr std::size_t kStrip = 2;
        // A header claiming a huge raster is GDAL's to read (sparse blocks read as zeros), not ours: skip it.
        if (double(r.height()) * double(r.width()) * double(r.bands()) > double(1 << 22)) return;
        std::vector<float> spectra;
        std::vector<std::uint8_t> mask;
        for (std::size_t y0 = 0; y0 < r.height(); y0 += kStrip) {
          const std::size_t rows = std::min(kStrip, r.height() - y0);
          spectra.assign(rows * r.width() * r.bands(), -1.0f);
          mask.assign(rows * r.width(), 2);
          r.read_rows(y0, rows, spectra, mask);
          for (const std::uint8_t v : mask) check(v == 0 || v == 1, "mask holds 0 or 1");
        }
      },
      p.string());
}

void spc(std::span<const std::uint8_t> input) {
  expect_clean(
      [&] {
        const codec::SpcCoefficients c = codec::decode_spc_coefficients(input, "fuzz.spc");
        check(c.k() > 0 && c.bands() > 0, "a non-empty basis");
        check(c.values.size() == brdf::kMerlCells * c.k() && c.valid.size() == brdf::kMerlCells, "one entry per cell");
        check_grid(c.wavelengths, c.bands());
        check(std::isfinite(c.scale) && c.scale > 0, "finite positive scale");
        check(c.basis.allFinite(), "finite basis");
        for (std::size_t i = 0; i < c.values.size(); ++i)
          check(std::isfinite(c.values[i]) && (c.valid[i / c.k()] || c.values[i] == 0),
                "finite values, 0 without data");
        const store::Grid g = codec::expand_spc(c);
        check(g.bands() == c.bands() && g.brdf.size() == c.bands() * brdf::kMerlCells, "the grid of the coefficients");
        for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell)
          for (std::size_t b = 0; b < g.bands(); ++b) {
            const float v = g.brdf[b * brdf::kMerlCells + cell];
            check(c.valid[cell] ? std::isfinite(v) && v >= 0 : v < 0, "x >= 0 with data, negative without");
          }
        const codec::SpcBasis basis = codec::spc_basis(input, "fuzz.spc");
        check(basis.rows.rows() == c.basis.rows() && basis.rows.cols() == c.basis.cols(), "the same basis");
      },
      "fuzz.spc");
}

void spgrid(std::span<const std::uint8_t> input) {
  if (input.empty()) return;
  std::string bytes(text_of(input).substr(1));
  constexpr std::size_t kHeader = 40;
  if (input[0] % 2 == 0 && input.size() > 1 + 16) {
    std::uint32_t bands = 0;
    std::memcpy(&bands, input.data() + 1 + 12, sizeof bands);
    if (bands >= 1 && bands <= 4) {
      bytes = expand(input, kHeader, codec::grid_file_bytes(bands));
      if (input[0] == 0) {
        const uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), uInt(bytes.size() - 4));
        const auto stored = std::uint32_t(crc);
        std::memcpy(bytes.data() + bytes.size() - 4, &stored, sizeof stored);
      }
    }
  }
  const fs::path p = write("fuzz.spgrid", bytes);
  expect_clean([&] { check_brdf_grid(codec::read_grid_file(p)); }, p.string());
}

void merl(std::span<const std::uint8_t> input) {
  if (input.empty()) return;
  const std::string bytes =
      input[0] % 2 ? std::string(text_of(input).substr(1)) : expand(input, 12, codec::kMerlFileBytes);
  const fs::path p = write("fuzz.binary", bytes);
  expect_clean(
      [&] {
        const codec::MerlBrdf b = codec::read_merl(p);
        check(b.raw.size() == 3 * brdf::kMerlCells, "three planes of 90 x 90 x 180");
        for (const double v : b.raw) check(std::isfinite(v), "finite values");
      },
      p.string());
}

void rgl_bsdf(std::span<const std::uint8_t> input) {
  const fs::path p = write("fuzz.bsdf", text_of(input));
  expect_clean(
      [&] {
        const codec::RglBsdf b = codec::read_rgl_bsdf(p);
        check(b.values.size() == b.theta_i.size() * b.channels() * b.resolution * b.resolution, "values size");
        const codec::RglEvaluator e(b);
        std::vector<double> f(e.channels());
        for (double ti : {0.0, 0.7, 1.4})
          for (double to : {0.1, 0.9})
            for (double po : {0.0, 2.0}) {
              e.eval(Eigen::Vector3d(std::sin(ti), 0, std::cos(ti)),
                     Eigen::Vector3d(std::sin(to) * std::cos(po), std::sin(to) * std::sin(po), std::cos(to)), f);
              for (double v : f) check(!std::isnan(v) && v >= 0, "f is a number and not negative");
            }
      },
      "fuzz.bsdf");
}

void nbrdf(std::span<const std::uint8_t> input) {
  const fs::path p = write("input.h5", text_of(input));
  expect_clean(
      [&] {
        const store::NbrdfWeights w = store::read_nbrdf(p);
        using W = store::NbrdfWeights;
        check(w.kernel1.size() == W::kInputs * W::kHidden && w.bias1.size() == W::kHidden, "layer 1 shape");
        check(w.kernel2.size() == W::kHidden * W::kHidden && w.bias2.size() == W::kHidden, "layer 2 shape");
        check(w.kernel3.size() == W::kHidden * W::kOutputs && w.bias3.size() == W::kOutputs, "layer 3 shape");
        for (const auto* v : {&w.kernel1, &w.bias1, &w.kernel2, &w.bias2, &w.kernel3, &w.bias3})
          for (const float x : *v) check(std::isfinite(x), "finite weights");
      },
      p.string());
}

void filters_csv(std::span<const std::uint8_t> input) {
  expect_clean(
      [&] {
        const acquire::FilterSet f = acquire::parse_filters_csv(text_of(input), "input.csv");
        check(f.nm.size() >= 2 && f.size() == f.names.size(), "a tabulation and named filters");
        for (std::size_t i = 1; i < f.nm.size(); ++i) check(f.nm[i] > f.nm[i - 1], "increasing wavelengths");
        for (const auto& t : f.transmission) {
          check(t.size() == f.nm.size(), "one value per wavelength");
          for (const double v : t) check(v >= 0 && v <= 1, "transmissions in [0, 1]");
        }
        const std::vector<double> bands = {420, 570, 720};
        acquire::check_filters(f, bands, "input.csv");
        for (std::size_t k = 0; k < f.size(); ++k) check(f.at(k, 570) >= 0 && f.at(k, 570) <= 1, "at() in [0, 1]");
      },
      "input.csv");
}

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {{"envi_header", envi_header},
                                          {"envi", envi},
                                          {"mat", mat},
                                          {"mask", mask},
                                          {"text_library", text_library},
                                          {"csv", csv},
                                          {"gdal", gdal},
                                          {"spc", spc},
                                          {"spgrid", spgrid},
                                          {"merl", merl},
                                          {"rgl_bsdf", rgl_bsdf},
                                          {"nbrdf", nbrdf},
                                          {"filters_csv", filters_csv}};
  return all;
}

}  // namespace specula::fuzz
