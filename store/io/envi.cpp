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

namespace specula::store {
namespace {

constexpr std::uint64_t kMaxBytes = std::uint64_t{1} << 40;
constexpr double kWriteIgnoreValue = -9999.0;

struct Field {
  std::string value;
  std::size_t line = 0;
};
using Fields = std::map<std::string, Field, std::less<>>;

std::string key_of(std::string_view raw) { return collapse_spaces(lower(raw)); }

std::vector<std::string_view> split_lines(std::string_view text) {
  std::vector<std::string_view> lines;
  std::size_t start = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\n' || text[i] == '\r') {
      lines.push_back(text.substr(start, i - start));
      if (text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      start = i + 1;
    }
  }
  if (start < text.size()) lines.push_back(text.substr(start));
  return lines;
}

Fields parse_fields(std::string_view text, const std::string& filename) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  const auto lines = split_lines(text);
  if (lines.empty() || lower(trim(lines[0])) != "envi")
    throw InputError(filename + ": not an ENVI header (the first line must be \"ENVI\", found \"" +
                     printable(lines.empty() ? std::string_view{} : trim(lines[0])) +
                     "\"); give the .hdr file that belongs to the image");
  Fields fields;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::size_t line_no = i + 1;
    const auto line = trim(lines[i]);
    if (line.empty() || line.front() == ';') continue;
    const auto eq = line.find('=');
    if (eq == std::string_view::npos)
      throw InputError(filename + ": line " + std::to_string(line_no) + ": expected \"key = value\", found \"" +
                       printable(line) + "\"; fix or remove the line");
    std::string key = key_of(line.substr(0, eq));
    if (key.empty())
      throw InputError(filename + ": line " + std::to_string(line_no) + ": \"" + printable(line) +
                       "\" has no key before '='; fix or remove the line");
    auto value = trim(line.substr(eq + 1));
    std::string stored;
    if (value.starts_with('{')) {
      std::string_view rest = value.substr(1);
      std::size_t j = i;
      for (;;) {
        const auto close = rest.find('}');
        if (close != std::string_view::npos) {
          stored += rest.substr(0, close);
          if (!trim(rest.substr(close + 1)).empty())
            throw InputError(filename + ": line " + std::to_string(j + 1) + ": text \"" +
                             printable(trim(rest.substr(close + 1))) + "\" after the '}' closing '" + key +
                             "'; put it on its own line");
          break;
        }
        stored += rest;
        if (++j == lines.size())
          throw InputError(filename + ": line " + std::to_string(line_no) + ": the '{' opening '" + key +
                           "' is never closed; add the missing '}'");
        stored += '\n';
        rest = lines[j];
      }
      i = j;
      stored = std::string(trim(stored));
    } else {
      stored = std::string(value);
    }
    fields[std::move(key)] = Field{std::move(stored), line_no};
  }
  return fields;
}

[[noreturn]] void bad_field(const std::string& filename, const std::string& key, const Field& f,
                            const std::string& problem) {
  throw InputError(filename + ": line " + std::to_string(f.line) + ": " + key + " = " + printable(f.value) + " " +
                   problem);
}

std::uint64_t parse_unsigned(const std::string& filename, const std::string& key, const Field& f) {
  auto v = trim(f.value);
  if (v.starts_with('+')) v.remove_prefix(1);
  std::uint64_t out = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  if (v.empty() || ec == std::errc::invalid_argument || ptr != v.data() + v.size())
    bad_field(filename, key, f, "is not a whole number; write a non-negative integer");
  if (ec == std::errc::result_out_of_range) bad_field(filename, key, f, "is out of range; the header is corrupt");
  return out;
}

double parse_real(std::string_view text, bool& ok) {
  auto v = trim(text);
  if (v.starts_with('+')) {
    v.remove_prefix(1);
    if (v.starts_with('-') || v.starts_with('+')) v = {};
  }
  double out = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  ok = !v.empty() && ec == std::errc{} && ptr == v.data() + v.size() && std::isfinite(out);
  return out;
}

std::vector<std::string_view> split_list(std::string_view v) {
  std::vector<std::string_view> items;
  if (trim(v).empty()) return items;
  std::size_t start = 0;
  for (;;) {
    const auto comma = v.find(',', start);
    items.push_back(trim(v.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return items;
}

std::vector<double> parse_real_list(const std::string& filename, const std::string& key, const Field& f,
                                    std::size_t bands, const char* axis = "bands") {
  const auto items = split_list(f.value);
  if (items.size() != bands)
    throw InputError(filename + ": line " + std::to_string(f.line) + ": " + key + " has " +
                     std::to_string(items.size()) + " values but " + axis + " = " + std::to_string(bands) +
                     "; give one value per band");
  std::vector<double> out;
  out.reserve(items.size());
  for (std::size_t i = 0; i < items.size(); ++i) {
    bool ok = false;
    const double d = parse_real(items[i], ok);
    if (!ok)
      throw InputError(filename + ": line " + std::to_string(f.line) + ": " + key + " value " + std::to_string(i + 1) +
                       " \"" + printable(items[i]) + "\" is not a finite number; fix the list");
    out.push_back(d);
  }
  return out;
}

std::size_t bytes_per_sample(int data_type) {
  switch (data_type) {
    case 1: return 1;
    case 2: return 2;
    case 3: return 4;
    case 4: return 4;
    case 5: return 8;
    case 12: return 2;
    default: return 0;
  }
}

const char* interleave_name(Interleave il) {
  switch (il) {
    case Interleave::bsq: return "bsq";
    case Interleave::bil: return "bil";
    case Interleave::bip: return "bip";
  }
  return "bsq";
}

// Factor to nm, 0 for "no physical wavelengths" (absent, unknown or index), -1 for an unsupported unit.
double unit_factor(const std::string& units) {
  const std::string u = lower(trim(units));
  if (u == "nanometers" || u == "nanometer" || u == "nanometres" || u == "nanometre" || u == "nm") return 1.0;
  if (u == "micrometers" || u == "micrometer" || u == "micrometres" || u == "micrometre" || u == "microns" ||
      u == "micron" || u == "um" || u == "\xC2\xB5m" || u == "\xCE\xBCm")
    return 1000.0;
  if (u.empty() || u == "unknown") return 0.0;
  return -1.0;
}

std::string format_real(double v) {
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc{}) throw LibraryError("cannot format " + std::to_string(v));
  return {buf.data(), ptr};
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

bool iequals_ext(const std::filesystem::path& p, std::string_view ext) {
  return lower(p.extension().string()) == ext;
}

struct Paths {
  std::filesystem::path header, data;
};

bool is_file(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec);
}

Paths locate(const std::filesystem::path& path) {
  if (!is_file(path))
    throw InputError(path.string() + ": no such file; give the ENVI .hdr or its data file");
  std::vector<std::filesystem::path> tried;
  if (iequals_ext(path, ".hdr")) {
    std::filesystem::path base = path;
    base.replace_extension();
    for (const char* ext : {"", ".raw", ".img", ".dat", ".bsq", ".bil", ".bip", ".sli", ".RAW", ".IMG", ".DAT",
                            ".BSQ", ".BIL", ".BIP", ".SLI"}) {
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
  throw InputError(path.string() + ": no ENVI header beside it (looked for " + replaced.filename().string() +
                   " and " + appended.filename().string() + "); give the .hdr path");
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

// An open output file that remembers the first failure instead of throwing mid-write.
class Sink {
 public:
  explicit Sink(std::FILE* f) : f_(f) {}
  void seek(std::uint64_t offset) {
    if (ok_ && fseeko(f_, static_cast<off_t>(offset), SEEK_SET) != 0) fail();
  }
  void write(const void* data, std::size_t n) {
    if (ok_ && std::fwrite(data, 1, n, f_) != n) fail();
  }
  bool ok() const { return ok_; }
  int error() const { return err_; }

 private:
  void fail() {
    ok_ = false;
    err_ = errno;
  }
  std::FILE* f_;
  bool ok_ = true;
  int err_ = 0;
};

// Writes target atomically; `fill` writes the content through a Sink.
void write_file(const std::filesystem::path& target, const std::function<void(Sink&)>& fill) {
  AtomicOutput out(target);
  std::FILE* f = std::fopen(out.temp_path().c_str(), "wb");
  if (!f) throw LibraryError(target.string() + ": cannot create " + out.temp_path().string() + ": " +
                             std::strerror(errno));
  Sink sink(f);
  try {
    fill(sink);
  } catch (...) {
    std::fclose(f);
    throw;
  }
  int err = sink.error();
  bool ok = sink.ok();
  if (std::fclose(f) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (!ok) throw LibraryError(target.string() + ": write failed: " + std::strerror(err));
  out.commit();
}

// Rows per block so that one block of the cube (all bands) is about 2 MiB.
std::size_t rows_per_block(std::size_t width, std::size_t bands) {
  return std::max<std::size_t>(1, (std::size_t{2} << 20) / (width * bands * sizeof(float)));
}

// Reads the data file of `h` into cube (lines x samples x bands), checking its size first.
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

bool EnviHeader::is_library() const { return lower(trim(file_type)) == "envi spectral library"; }

EnviHeader parse_envi_header(std::string_view text, const std::string& filename) {
  const Fields fields = parse_fields(text, filename);
  const auto find = [&](const char* key) -> const Field* {
    const auto it = fields.find(std::string_view(key));
    return it == fields.end() ? nullptr : &it->second;
  };
  const auto require = [&](const char* key, const char* example) -> const Field& {
    const Field* f = find(key);
    if (!f)
      throw InputError(filename + ": required field '" + key + "' is missing; add a line such as '" + example +
                       "'");
    return *f;
  };

  EnviHeader h;
  const auto dimension = [&](const char* key, const char* example) {
    const Field& f = require(key, example);
    const std::uint64_t v = parse_unsigned(filename, key, f);
    if (v == 0) bad_field(filename, key, f, "must be at least 1");
    if (v > kMaxBytes) bad_field(filename, key, f, "is absurdly large; the header is corrupt");
    return static_cast<std::size_t>(v);
  };
  h.samples = dimension("samples", "samples = 640");
  h.lines = dimension("lines", "lines = 480");
  h.bands = dimension("bands", "bands = 31");

  {
    const Field& f = require("data type", "data type = 4");
    const std::uint64_t v = parse_unsigned(filename, "data type", f);
    if (v > 1000 || bytes_per_sample(static_cast<int>(v)) == 0)
      bad_field(filename, "data type", f,
                "is not supported; convert the image to data type 1 (uint8), 2 (int16), 3 (int32), 4 (float32), "
                "5 (float64) or 12 (uint16)");
    h.data_type = static_cast<int>(v);
  }
  {
    const Field& f = require("interleave", "interleave = bsq");
    const std::string v = lower(trim(f.value));
    if (v == "bsq") h.interleave = Interleave::bsq;
    else if (v == "bil") h.interleave = Interleave::bil;
    else if (v == "bip") h.interleave = Interleave::bip;
    else bad_field(filename, "interleave", f, "is not one of bsq, bil, bip");
  }
  if (const Field* f = find("byte order")) {
    const std::uint64_t v = parse_unsigned(filename, "byte order", *f);
    if (v > 1) bad_field(filename, "byte order", *f, "must be 0 (little endian) or 1 (big endian)");
    h.byte_order = static_cast<int>(v);
  }
  if (const Field* f = find("header offset")) {
    const std::uint64_t v = parse_unsigned(filename, "header offset", *f);
    if (v > kMaxBytes) bad_field(filename, "header offset", *f, "is absurdly large; the header is corrupt");
    h.header_offset = static_cast<std::size_t>(v);
  }

  const std::size_t bps = bytes_per_sample(h.data_type);
  std::uint64_t elements = 0, bytes = 0;
  if (__builtin_mul_overflow(std::uint64_t{h.samples}, std::uint64_t{h.lines}, &elements) ||
      __builtin_mul_overflow(elements, std::uint64_t{h.bands}, &elements) ||
      __builtin_mul_overflow(elements, std::uint64_t{std::max<std::size_t>(bps, sizeof(float))}, &bytes) ||
      bytes > kMaxBytes)
    throw InputError(filename + ": samples " + std::to_string(h.samples) + " x lines " + std::to_string(h.lines) +
                     " x bands " + std::to_string(h.bands) +
                     " exceeds the 1 TiB limit for one image; the header is corrupt or the image must be split");

  if (const Field* f = find("file type")) h.file_type = std::string(trim(f->value));
  // A library's spectral axis is its samples; an image's is its bands.
  const std::size_t spectral = h.is_library() ? h.samples : h.bands;
  const char* axis = h.is_library() ? "samples" : "bands";
  if (h.is_library() && h.bands != 1)
    bad_field(filename, "bands", *find("bands"), "must be 1 in an ENVI Spectral Library (samples are its bands)");
  if (const Field* f = find("wavelength units")) h.wavelength_units = std::string(trim(f->value));
  if (const Field* f = find("wavelength")) {
    h.wavelength = parse_real_list(filename, "wavelength", *f, spectral, axis);
    // Wavelengths may come unsorted: the readers sort the bands by them (kept_band_order).
    if (*std::min_element(h.wavelength.begin(), h.wavelength.end()) <= 0)
      throw InputError(filename + ": line " + std::to_string(f->line) + ": wavelength " +
                       format_real(*std::min_element(h.wavelength.begin(), h.wavelength.end())) +
                       " is not positive; fix the wavelength list");
  }
  if (const Field* f = find("fwhm")) {
    h.fwhm = parse_real_list(filename, "fwhm", *f, spectral, axis);
    for (std::size_t i = 0; i < h.fwhm.size(); ++i)
      if (h.fwhm[i] < 0)
        throw InputError(filename + ": line " + std::to_string(f->line) + ": fwhm value " + std::to_string(i + 1) +
                         " is negative; fix the fwhm list");
  }
  if (const Field* f = find("data ignore value")) {
    bool ok = false;
    const double v = parse_real(f->value, ok);
    if (!ok) bad_field(filename, "data ignore value", *f, "is not a finite number");
    h.data_ignore_value = v;
  }
  if (const Field* f = find("band names")) {
    const auto items = split_list(f->value);
    if (items.size() != h.bands)
      throw InputError(filename + ": line " + std::to_string(f->line) + ": band names has " +
                       std::to_string(items.size()) + " names but bands = " + std::to_string(h.bands) +
                       "; give one name per band");
    h.band_names.assign(items.begin(), items.end());
  }
  if (const Field* f = find("bbl")) {
    const auto flags = parse_real_list(filename, "bbl", *f, spectral, axis);
    for (std::size_t i = 0; i < flags.size(); ++i) {
      if (flags[i] != 0 && flags[i] != 1)
        throw InputError(filename + ": line " + std::to_string(f->line) + ": bbl value " + std::to_string(i + 1) +
                         " is " + format_real(flags[i]) + "; write 1 for a good band and 0 for a bad one");
      h.bbl.push_back(flags[i] == 1);
    }
  }
  if (const Field* f = find("spectra names")) {
    const auto items = split_list(f->value);
    if (h.is_library() && items.size() != h.lines)
      throw InputError(filename + ": line " + std::to_string(f->line) + ": spectra names has " +
                       std::to_string(items.size()) + " names but lines = " + std::to_string(h.lines) +
                       "; give one name per spectrum");
    h.spectra_names.assign(items.begin(), items.end());
  }
  if (const Field* f = find("description")) h.description = f->value;
  return h;
}

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
      throw InputError(hname + ": the image has " + std::to_string(h.bands) + " bands but the `wavelengths` option gives " +
                       std::to_string(fallback.size()) + "; pass one wavelength per band");
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

void write_envi(const std::filesystem::path& data_path, const Cube& cube, Interleave interleave) {
  if (iequals_ext(data_path, ".hdr"))
    throw UsageError("write_envi: " + data_path.string() + " is the header name; give the data file (e.g. .raw)");
  const std::size_t H = cube.height, W = cube.width, B = cube.bands;
  if (H == 0 || W == 0 || B == 0 || cube.data.size() != H * W * B)
    throw UsageError("write_envi: cube data has " + std::to_string(cube.data.size()) + " values for " +
                     std::to_string(H) + " x " + std::to_string(W) + " x " + std::to_string(B));
  if (!cube.mask.empty() && cube.mask.size() != H * W)
    throw UsageError("write_envi: mask has " + std::to_string(cube.mask.size()) + " entries, need " +
                     std::to_string(H * W));
  if (!cube.wavelengths.empty() && cube.wavelengths.size() != B)
    throw UsageError("write_envi: " + std::to_string(cube.wavelengths.size()) + " wavelengths for " +
                     std::to_string(B) + " bands");
  if (!cube.fwhm.empty() && cube.fwhm.size() != B)
    throw UsageError("write_envi: " + std::to_string(cube.fwhm.size()) + " fwhm values for " + std::to_string(B) +
                     " bands");

  const bool masked = std::find(cube.mask.begin(), cube.mask.end(), std::uint8_t{0}) != cube.mask.end();
  const float fill = static_cast<float>(kWriteIgnoreValue);
  const auto word = [&](std::size_t y, std::size_t x, std::size_t b) {
    const float v = cube.valid(y, x) ? cube.data[(y * W + x) * B + b] : fill;
    const auto w = std::bit_cast<std::uint32_t>(v);
    return std::endian::native == std::endian::big ? __builtin_bswap32(w) : w;
  };
  const std::size_t block = rows_per_block(W, B);
  write_file(data_path, [&](Sink& sink) {
    std::vector<std::uint32_t> words;
    for (std::size_t y0 = 0; y0 < H; y0 += block) {
      const std::size_t k = std::min(block, H - y0);
      switch (interleave) {
        case Interleave::bsq:
          words.resize(k * W);
          for (std::size_t b = 0; b < B; ++b) {
            for (std::size_t yy = 0; yy < k; ++yy)
              for (std::size_t x = 0; x < W; ++x) words[yy * W + x] = word(y0 + yy, x, b);
            sink.seek((std::uint64_t{b} * H + y0) * W * sizeof(std::uint32_t));
            sink.write(words.data(), words.size() * sizeof(std::uint32_t));
          }
          break;
        case Interleave::bil:
          words.resize(k * B * W);
          for (std::size_t yy = 0; yy < k; ++yy)
            for (std::size_t b = 0; b < B; ++b)
              for (std::size_t x = 0; x < W; ++x) words[(yy * B + b) * W + x] = word(y0 + yy, x, b);
          sink.write(words.data(), words.size() * sizeof(std::uint32_t));
          break;
        case Interleave::bip:
          words.resize(k * W * B);
          for (std::size_t yy = 0; yy < k; ++yy)
            for (std::size_t x = 0; x < W; ++x)
              for (std::size_t b = 0; b < B; ++b) words[(yy * W + x) * B + b] = word(y0 + yy, x, b);
          sink.write(words.data(), words.size() * sizeof(std::uint32_t));
          break;
      }
    }
  });

  std::string hdr = "ENVI\ndescription = {written by specula}\n";
  hdr += "samples = " + std::to_string(W) + "\nlines = " + std::to_string(H) + "\nbands = " + std::to_string(B) +
         "\nheader offset = 0\nfile type = ENVI Standard\ndata type = 4\ninterleave = " +
         interleave_name(interleave) + "\nbyte order = 0\n";
  const auto list = [](std::span<const double> v) {
    std::string s = "{";
    for (std::size_t k = 0; k < v.size(); ++k) s += (k ? ", " : " ") + format_real(v[k]);
    return s + " }";
  };
  if (!cube.wavelengths.empty())
    hdr += "wavelength units = Nanometers\nwavelength = " + list(cube.wavelengths.values()) + "\n";
  if (!cube.fwhm.empty()) hdr += "fwhm = " + list(cube.fwhm) + "\n";
  if (masked) hdr += "data ignore value = " + format_real(kWriteIgnoreValue) + "\n";
  std::string units;
  for (char c : cube.units)
    if (c != '\n' && c != '\r' && c != '{' && c != '}') units += c;
  if (!trim(units).empty()) hdr += "specula units = " + std::string(trim(units)) + "\n";

  std::filesystem::path header_path = data_path;
  header_path.replace_extension(".hdr");
  write_file(header_path, [&](Sink& sink) { sink.write(hdr.data(), hdr.size()); });
}

}  // namespace specula::store
