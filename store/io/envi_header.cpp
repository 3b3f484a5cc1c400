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

std::size_t bytes_per_sample(int data_type) {
  switch (data_type) {
    case 1:
      return 1;
    case 2:
      return 2;
    case 3:
      return 4;
    case 4:
      return 4;
    case 5:
      return 8;
    case 12:
      return 2;
    default:
      return 0;
  }
}

std::string format_real(double v) {
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc{}) throw LibraryError("cannot format " + std::to_string(v));
  return {buf.data(), ptr};
}

}  // namespace envi_detail

namespace {

using namespace envi_detail;

constexpr std::uint64_t kMaxBytes = std::uint64_t{1} << 40;

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

// The lookups of one header's fields: find (nullptr when absent) and require (InputError with an example line).
struct FieldLookup {
  const Fields& fields;
  const std::string& filename;
  const Field* find(const char* key) const {
    const auto it = fields.find(std::string_view(key));
    return it == fields.end() ? nullptr : &it->second;
  }
  const Field& require(const char* key, const char* example) const {
    const Field* f = find(key);
    if (!f)
      throw InputError(filename + ": required field '" + key + "' is missing; add a line such as '" + example + "'");
    return *f;
  }
};

// The fields that lay out the data file: dimensions, data type, interleave, byte order, offset; checked for size.
void parse_layout(const FieldLookup& lookup, EnviHeader& h) {
  const std::string& filename = lookup.filename;
  const auto find = [&](const char* key) { return lookup.find(key); };
  const auto require = [&](const char* key, const char* example) -> const Field& {
    return lookup.require(key, example);
  };
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
    if (v == "bsq")
      h.interleave = Interleave::bsq;
    else if (v == "bil")
      h.interleave = Interleave::bil;
    else if (v == "bip")
      h.interleave = Interleave::bip;
    else
      bad_field(filename, "interleave", f, "is not one of bsq, bil, bip");
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
}

// The fields about the spectral axis and names: file type, wavelengths, fwhm, ignore value, band and spectra names,
// bbl, description.
void parse_spectral(const FieldLookup& lookup, EnviHeader& h) {
  const std::string& filename = lookup.filename;
  const auto find = [&](const char* key) { return lookup.find(key); };
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
}

}  // namespace

bool EnviHeader::is_library() const { return lower(trim(file_type)) == "envi spectral library"; }

EnviHeader parse_envi_header(std::string_view text, const std::string& filename) {
  const Fields fields = parse_fields(text, filename);
  const FieldLookup lookup{fields, filename};
  EnviHeader h;
  parse_layout(lookup, h);
  parse_spectral(lookup, h);
  return h;
}

}  // namespace specula::store
