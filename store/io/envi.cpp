#include "specula/store/io/envi.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <span>
#include <system_error>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/core/text.h"
#include "specula/store/io/envi_detail.h"

namespace specula::store {
namespace envi_detail {

bool iequals_ext(const std::filesystem::path& p, std::string_view ext) { return lower(p.extension().string()) == ext; }

std::size_t rows_per_block(std::size_t width, std::size_t bands) {
  return std::max<std::size_t>(1, (std::size_t{2} << 20) / (width * bands * sizeof(float)));
}

}  // namespace envi_detail

namespace {

using namespace envi_detail;

double unit_factor(const std::string& units) {
  const std::string u = lower(trim(units));
  if (u == "nanometers" || u == "nanometer" || u == "nanometres" || u == "nanometre" || u == "nm") return 1.0;
  if (u == "micrometers" || u == "micrometer" || u == "micrometres" || u == "micrometre" || u == "microns" ||
      u == "micron" || u == "um" || u == "\xC2\xB5m" || u == "\xCE\xBCm")
    return 1000.0;
  if (u.empty() || u == "unknown") return 0.0;
  return -1.0;
}

template <typename U>
U load(const unsigned char* p, bool swap) {
  U u;
  std::memcpy(&u, p, sizeof u);
  if (swap) {
    if constexpr (sizeof(U) == 2) u = __builtin_bswap16(u);
    if constexpr (sizeof(U) == 4) u = __builtin_bswap32(u);
    if constexpr (sizeof(U) == 8) u = __builtin_bswap64(u);
  }
  return u;
}

void decode(const unsigned char* src, std::size_t n, int data_type, bool swap, float* out) {
  switch (data_type) {
    case 1:
      for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(src[i]);
      break;
    case 2:
      for (std::size_t i = 0; i < n; ++i)
        out[i] = static_cast<float>(std::bit_cast<std::int16_t>(load<std::uint16_t>(src + 2 * i, swap)));
      break;
    case 12:
      for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(load<std::uint16_t>(src + 2 * i, swap));
      break;
    case 3:
      for (std::size_t i = 0; i < n; ++i)
        out[i] = static_cast<float>(std::bit_cast<std::int32_t>(load<std::uint32_t>(src + 4 * i, swap)));
      break;
    case 4:
      for (std::size_t i = 0; i < n; ++i) out[i] = std::bit_cast<float>(load<std::uint32_t>(src + 4 * i, swap));
      break;
    case 5:
      for (std::size_t i = 0; i < n; ++i)
        out[i] = static_cast<float>(std::bit_cast<double>(load<std::uint64_t>(src + 8 * i, swap)));
      break;
    default:
      throw UsageError("decode: unsupported ENVI data type " + std::to_string(data_type));
  }
}

struct Paths {
  std::filesystem::path header, data;
};

bool is_file(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec);
}

Paths locate(const std::filesystem::path& path) {
  if (!is_file(path)) throw InputError(path.string() + ": no such file; give the ENVI .hdr or its data file");
  std::vector<std::filesystem::path> tried;
  if (iequals_ext(path, ".hdr")) {
    std::filesystem::path base = path;
    base.replace_extension();
    for (const char* ext : {"", ".raw", ".img", ".dat", ".bsq", ".bil", ".bip", ".sli", ".RAW", ".IMG", ".DAT", ".BSQ",
                            ".BIL", ".BIP", ".SLI"}) {
      std::filesystem::path cand = base;
      cand += ext;
      if (is_file(cand)) return {path, cand};
      tried.push_back(cand);
    }
    std::string list;
    for (const auto& t : tried) list += (list.empty() ? "" : ", ") + t.filename().string();
    throw InputError(path.string() + ": no data file beside the header (looked for " + list +
                     "); give the data file path instead");
  }
  std::filesystem::path replaced = path;
  replaced.replace_extension(".hdr");
  std::filesystem::path upper = path;
  upper.replace_extension(".HDR");
  std::filesystem::path appended = path;
  appended += ".hdr";
  for (const auto& cand : {replaced, upper, appended})
    if (is_file(cand)) return {cand, path};
  throw InputError(path.string() + ": no ENVI header beside it (looked for " + replaced.filename().string() + " and " +
                   appended.filename().string() + "); give the .hdr path");
}

std::string read_text(const std::filesystem::path& p) {
  std::FILE* f = std::fopen(p.c_str(), "rb");
  if (!f) throw InputError(p.string() + ": cannot open: " + std::strerror(errno));
  std::string text;
  std::array<char, 65536> buf{};
  for (;;) {
    const std::size_t n = std::fread(buf.data(), 1, buf.size(), f);
    text.append(buf.data(), n);
    if (n < buf.size()) break;
    if (text.size() > (std::size_t{64} << 20)) {
      std::fclose(f);
      throw InputError(p.string() + ": larger than 64 MiB, which no ENVI header is; give the .hdr file");
    }
  }
  const bool failed = std::ferror(f) != 0;
  const int err = errno;
  if (std::fclose(f) != 0 || failed)
    throw LibraryError(p.string() + ": read failed: " + std::strerror(failed ? err : errno));
  return text;
}

void read_data(const Paths& paths, const EnviHeader& h, const std::string& hname, Cube& cube) {
  const std::size_t bps = bytes_per_sample(h.data_type);
  const std::uint64_t elements = std::uint64_t{h.samples} * h.lines * h.bands;
  const std::uint64_t needed = elements * bps + h.header_offset;
  std::error_code ec;
  const std::uint64_t actual = std::filesystem::file_size(paths.data, ec);
  if (ec) throw InputError(paths.data.string() + ": cannot get its size: " + ec.message());
  if (actual != needed)
    throw InputError(hname + ": data file " + paths.data.filename().string() + " has " + std::to_string(actual) +
                     " bytes, header needs " + std::to_string(needed) + " (samples " + std::to_string(h.samples) +
                     " x lines " + std::to_string(h.lines) + " x bands " + std::to_string(h.bands) + " x " +
                     std::to_string(bps) + " bytes + offset " + std::to_string(h.header_offset) + ")" +
                     (actual < needed ? "; the data file is truncated" : "; the header does not match the data"));

  const std::size_t H = h.lines, W = h.samples, B = h.bands;
  cube.resize(H, W, B);

  std::FILE* f = std::fopen(paths.data.c_str(), "rb");
  if (!f) throw InputError(paths.data.string() + ": cannot open: " + std::strerror(errno));
  struct Closer {
    std::FILE* f;
    ~Closer() {
      if (f) std::fclose(f);
    }
  } closer{f};

  const bool swap = bps > 1 && ((h.byte_order == 1) != (std::endian::native == std::endian::big));
  std::vector<unsigned char> raw;
  std::vector<float> vals;
  const auto read_at = [&](std::uint64_t offset, std::size_t n) {
    raw.resize(n * bps);
    vals.resize(n);
    if (fseeko(f, static_cast<off_t>(h.header_offset + offset * bps), SEEK_SET) != 0)
      throw LibraryError(paths.data.string() + ": seek failed: " + std::strerror(errno));
    if (std::fread(raw.data(), 1, raw.size(), f) != raw.size())
      throw InputError(paths.data.string() + ": read failed" +
                       (std::ferror(f) ? ": " + std::string(std::strerror(errno)) : ": the file shrank while reading"));
    decode(raw.data(), n, h.data_type, swap, vals.data());
  };
  float* out = cube.data.data();
  const std::size_t block = rows_per_block(W, B);
  for (std::size_t y0 = 0; y0 < H; y0 += block) {
    const std::size_t k = std::min(block, H - y0);
    float* dst = out + y0 * W * B;
    switch (h.interleave) {
      case Interleave::bsq:
        for (std::size_t b = 0; b < B; ++b) {
          read_at((std::uint64_t{b} * H + y0) * W, k * W);
          for (std::size_t i = 0; i < k * W; ++i) dst[i * B + b] = vals[i];
        }
        break;
      case Interleave::bil:
        read_at(std::uint64_t{y0} * W * B, k * W * B);
        for (std::size_t yy = 0; yy < k; ++yy)
          for (std::size_t b = 0; b < B; ++b) {
            const float* src = vals.data() + (yy * B + b) * W;
            float* row = dst + yy * W * B + b;
            for (std::size_t x = 0; x < W; ++x) row[x * B] = src[x];
          }
        break;
      case Interleave::bip:
        read_at(std::uint64_t{y0} * W * B, k * W * B);
        std::copy(vals.begin(), vals.end(), dst);
        break;
    }
  }

  closer.f = nullptr;
  if (std::fclose(f) != 0) throw LibraryError(paths.data.string() + ": close failed: " + std::strerror(errno));
}

// The header's wavelengths in nm (empty with `problem` set when unusable); `factor` scales fwhm likewise.
std::vector<double> header_nm(const EnviHeader& h, double& factor, std::string& problem) {
  const std::string units_lower = lower(trim(h.wavelength_units));
  factor = unit_factor(h.wavelength_units);
  const std::size_t n = h.is_library() ? h.samples : h.bands;
  const double top = h.wavelength.empty() ? 0.0 : *std::max_element(h.wavelength.begin(), h.wavelength.end());
  if (h.wavelength.empty() || units_lower == "index") {
    problem = "the header has no wavelengths; give the `wavelengths` option FIRST:LAST:STEP (" + std::to_string(n) +
              " bands, e.g. 400:700:10 for 31) or add a 'wavelength' list";
  } else if (factor < 0) {
    problem = "wavelength units = " + printable(h.wavelength_units) +
              " is not supported; use Nanometers or Micrometers, or give the `wavelengths` option in nm";
  } else if (factor == 0 && top < 100) {
    problem = "wavelengths " + format_real(*std::min_element(h.wavelength.begin(), h.wavelength.end())) + "-" +
              format_real(top) +
              " have no wavelength units; add 'wavelength units = Micrometers' (or Nanometers) to the header";
  } else {
    factor = factor == 0 ? 1.0 : factor;
    std::vector<double> nm(h.wavelength);
    for (double& v : nm) v *= factor;
    return nm;
  }
  return {};
}

// The bands to keep (all, or those bbl marks good) in ascending order of their wavelengths `nm` (one per band, any
// order): a list ENVI allows unsorted is kept exactly, permuted, never resampled. InputError for a wavelength listed
// twice or a bbl marking every band bad.
std::vector<std::size_t> kept_band_order(const EnviHeader& h, const std::vector<double>& nm, bool honour_bbl,
                                         const std::string& hname) {
  std::vector<std::size_t> order;
  for (std::size_t b = 0; b < nm.size(); ++b)
    if (!honour_bbl || h.bbl.empty() || h.bbl[b]) order.push_back(b);
  if (order.empty())
    throw InputError(hname + ": bbl marks all " + std::to_string(nm.size()) +
                     " bands bad; fix the bbl list or pass honour_bbl = false to keep them");
  return ascending_band_order(nm, std::move(order), [&](std::size_t first, std::size_t second) {
    throw InputError(hname + ": wavelength " +
                     format_real(h.wavelength.size() == nm.size() ? h.wavelength[second] : nm[second]) +
                     " appears twice (bands " + std::to_string(first + 1) + " and " + std::to_string(second + 1) +
                     "); remove one of them");
  });
}

}  // namespace

Cube read_envi(const std::filesystem::path& path, const WavelengthGrid& fallback, bool honour_bbl) {
  const Paths paths = locate(path);
  const std::string hname = paths.header.string();
  const std::string text = read_text(paths.header);
  const EnviHeader h = parse_envi_header(text, hname);
  const Fields fields = parse_fields(text, hname);
  if (h.is_library())
    throw InputError(hname + ": file type = " + printable(h.file_type) +
                     " holds spectra, not an image; read it with read_envi_library (a collection)");

  Cube cube;
  cube.provenance.source_file = path.string();
  cube.provenance.importer = "envi";
  for (const char* key : {"specula units", "units"}) {
    const auto it = fields.find(std::string_view(key));
    if (it != fields.end() && !trim(it->second.value).empty()) {
      cube.units = std::string(trim(it->second.value));
      break;
    }
  }

  // The header's own wavelengths win; `problem` explains why they are unusable when there is no fallback.
  double factor = 1.0;
  std::string problem;
  std::vector<double> nm = header_nm(h, factor, problem), fwhm;
  if (problem.empty()) {
    fwhm = h.fwhm;
    for (double& v : fwhm) v *= factor;
  } else if (!fallback.empty()) {
    if (fallback.size() != h.bands)
      throw InputError(hname + ": the image has " + std::to_string(h.bands) +
                       " bands but the `wavelengths` option gives " + std::to_string(fallback.size()) +
                       "; pass one wavelength per band");
    nm.assign(fallback.values().begin(), fallback.values().end());
  } else {
    throw InputError(hname + ": " + problem);
  }
  const std::vector<std::size_t> order = kept_band_order(h, nm, honour_bbl, hname);

  Cube raw;
  read_data(paths, h, hname, raw);
  const std::size_t pixels = std::size_t(h.lines) * h.samples, B = order.size();
  std::vector<double> kept_nm;
  for (const std::size_t b : order) kept_nm.push_back(nm[b]);
  cube.wavelengths = WavelengthGrid(std::move(kept_nm), hname);
  if (!fwhm.empty())
    for (const std::size_t b : order) cube.fwhm.push_back(fwhm[b]);
  cube.height = raw.height;
  cube.width = raw.width;
  cube.bands = B;
  if (B == raw.bands && std::is_sorted(order.begin(), order.end())) {
    cube.data = std::move(raw.data);
  } else {
    cube.data.resize(pixels * B);
    for (std::size_t p = 0; p < pixels; ++p)
      for (std::size_t k = 0; k < B; ++k) cube.data[p * B + k] = raw.data[p * raw.bands + order[k]];
  }
  const std::size_t H = h.lines, W = h.samples;
  float* out = cube.data.data();
  if (h.data_ignore_value) {
    const float ignore = static_cast<float>(*h.data_ignore_value);
    std::vector<std::uint8_t> mask(H * W, 1);
    bool any = false;
    for (std::size_t p = 0; p < H * W; ++p) {
      const float* px = out + p * B;
      if (std::find(px, px + B, ignore) != px + B) {
        mask[p] = 0;
        any = true;
      }
    }
    if (any) cube.mask = std::move(mask);
  }
  return cube;
}

bool is_envi_library(const std::filesystem::path& path) {
  try {
    const Paths paths = locate(path);
    const std::string text = read_text(paths.header);
    const Fields fields = parse_fields(text, paths.header.string());
    const auto it = fields.find(std::string_view("file type"));
    return it != fields.end() && lower(trim(it->second.value)) == "envi spectral library";
  } catch (const Error&) {
    return false;
  }
}

Collection read_envi_library(const std::filesystem::path& path, bool honour_bbl, const WavelengthGrid& fallback) {
  const Paths paths = locate(path);
  const std::string hname = paths.header.string();
  const std::string text = read_text(paths.header);
  const EnviHeader h = parse_envi_header(text, hname);
  const Fields fields = parse_fields(text, hname);
  if (!h.is_library())
    throw InputError(hname + ": file type = " + printable(h.file_type.empty() ? "(absent)" : h.file_type) +
                     " is not ENVI Spectral Library; read it with read_envi (an image)");
  double factor = 1.0;
  std::string problem;
  std::vector<double> nm = header_nm(h, factor, problem);
  if (!problem.empty()) {
    if (fallback.empty()) throw InputError(hname + ": " + problem);
    if (fallback.size() != h.samples)
      throw InputError(hname + ": the library has " + std::to_string(h.samples) +
                       " bands (samples) but the `wavelengths` option gives " + std::to_string(fallback.size()) +
                       "; pass one wavelength per band");
    nm.assign(fallback.values().begin(), fallback.values().end());
  }

  Cube raw;
  read_data(paths, h, hname, raw);  // lines x samples x 1: spectrum i is row i
  const std::size_t N = h.lines, S = h.samples;

  const std::vector<std::size_t> order = kept_band_order(h, nm, honour_bbl, hname);

  Collection col;
  std::vector<double> grid;
  for (std::size_t b : order) grid.push_back(nm[b]);
  col.wavelengths = WavelengthGrid(std::move(grid), hname);
  col.values.resize(N * order.size());
  for (std::size_t i = 0; i < N; ++i)
    for (std::size_t k = 0; k < order.size(); ++k) {
      const float v = raw.data[i * S + order[k]];
      if (!std::isfinite(v))
        throw InputError(hname + ": spectrum " + std::to_string(i + 1) + " band " + std::to_string(order[k] + 1) +
                         " is " + format_real(v) + " (not finite); mark the band bad in bbl or fix the data");
      col.values[i * order.size() + k] = v;
    }
  for (std::size_t i = 0; i < N; ++i)
    col.names.push_back(h.spectra_names.empty() || h.spectra_names[i].empty() ? "spectrum_" + std::to_string(i + 1)
                                                                              : h.spectra_names[i]);
  for (const char* key : {"specula units", "units"}) {
    const auto it = fields.find(std::string_view(key));
    if (it != fields.end() && !trim(it->second.value).empty()) {
      col.units = std::string(trim(it->second.value));
      break;
    }
  }
  col.provenance.source_file = path.string();
  col.provenance.importer = "envi-library";
  return col;
}

}  // namespace specula::store
