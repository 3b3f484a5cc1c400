#include "specula/store/io/text_library.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::store {
namespace {

// splib07a marks deleted points with -1.23e34; anything at or below -1e34 is that marker.
constexpr double kUsgsMissingBelow = -1e34;

std::vector<std::string> read_lines(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw InputError(p.string() + ": cannot open; check the path");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(std::move(line));
  }
  if (in.bad()) throw InputError(p.string() + ": read failed");
  if (!lines.empty() && lines[0].starts_with("\xEF\xBB\xBF")) lines[0].erase(0, 3);
  return lines;
}

bool parse_number(std::string_view text, double& out) {
  auto v = trim(text);
  if (v.starts_with('+')) v.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  return !v.empty() && ec == std::errc{} && ptr == v.data() + v.size() && std::isfinite(out);
}

// Whether v survives the conversion to the store's float32 values.
bool fits_float(double v) { return std::abs(v) <= double(std::numeric_limits<float>::max()); }

[[noreturn]] void bad_line(const std::filesystem::path& p, std::size_t line, const std::string& problem) {
  throw InputError(p.string() + ": line " + std::to_string(line) + ": " + problem);
}

// One splib07a file: its title and one value per line (missing values kept as the marker).
struct UsgsFile {
  std::string title;
  std::vector<double> values;
};

UsgsFile read_usgs_file(const std::filesystem::path& p) {
  const auto lines = read_lines(p);
  if (lines.empty() || trim(lines[0]).empty())
    throw InputError(p.string() + ": empty or no title line; a splib07a file starts with its title");
  UsgsFile f;
  f.title = std::string(trim(lines[0]));
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto t = trim(lines[i]);
    if (t.empty()) {
      // Trailing blank lines are fine; a blank line inside the data is not.
      for (std::size_t j = i + 1; j < lines.size(); ++j)
        if (!trim(lines[j]).empty())
          bad_line(p, i + 1, "blank line inside the data; one value per line, remove the blank line");
      break;
    }
    double v = 0;
    if (!parse_number(t, v))
      bad_line(p, i + 1, "\"" + printable(t) + "\" is not a number; a splib07a file holds one value per line");
    if (!fits_float(v))
      bad_line(p, i + 1, "value " + num(v) + " is beyond the float32 range of a store; fix the value");
    f.values.push_back(v);
  }
  if (f.values.empty()) throw InputError(p.string() + ": title line but no values; the file is truncated");
  return f;
}

// The spectrum name of a title "splib07a Record=123: Acmite NMNH133746 Pyroxene ASDFRa AREF".
std::string usgs_name(const std::string& title) {
  const auto rec = title.find("Record=");
  if (rec != std::string::npos) {
    const auto colon = title.find(':', rec);
    if (colon != std::string::npos) {
      const std::string out = collapse_spaces(std::string_view(title).substr(colon + 1));
      if (!out.empty()) return out;
    }
  }
  return title;
}

std::string describe_nm(double v) { return num(v) + " nm"; }

}  // namespace

std::string sniff_text_library(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string first;
  if (!in || !std::getline(in, first)) return "";
  if (first.starts_with("\xEF\xBB\xBF")) first.erase(0, 3);
  const std::string l = lower(trim(first));
  if (l.starts_with("name:")) return "ecostress";
  if (l.starts_with("splib") || l.find("record=") != std::string::npos)
    return l.find("wavelength") != std::string::npos ? "usgs-wavelengths" : "usgs";
  return "";
}

TextLibrary read_usgs_spectra(std::span<const std::filesystem::path> spectra,
                              const std::filesystem::path& wavelengths) {
  if (spectra.empty()) throw UsageError("read_usgs_spectra: no spectrum files given");
  const UsgsFile wl = read_usgs_file(wavelengths);
  if (lower(wl.title).find("wavelength") == std::string::npos)
    throw InputError(wavelengths.string() + ": title \"" + printable(wl.title) +
                     "\" does not name Wavelengths; give the splib07a Wavelengths file of these spectra");
  const std::size_t B = wl.values.size();
  for (std::size_t b = 0; b < B; ++b)
    if (!(wl.values[b] > 0) && wl.values[b] > kUsgsMissingBelow)
      bad_line(wavelengths, b + 2, "wavelength " + num(wl.values[b]) + " is not positive; fix the file");

  TextLibrary out;
  std::vector<UsgsFile> kept;
  std::vector<std::string> names;
  for (const auto& p : spectra) {
    UsgsFile f = read_usgs_file(p);
    if (f.values.size() != B)
      throw InputError(p.string() + ": " + std::to_string(f.values.size()) + " values but " + wavelengths.string() +
                       " has " + std::to_string(B) + " wavelengths; give the Wavelengths file of this spectrometer");
    if (std::all_of(f.values.begin(), f.values.end(), [](double v) { return v <= kUsgsMissingBelow; })) {
      out.notes.push_back(p.string() + ": every value is the missing marker -1.23e34; spectrum dropped");
      continue;
    }
    names.push_back(usgs_name(f.title));
    kept.push_back(std::move(f));
  }
  if (kept.empty())
    throw InputError(spectra.front().string() +
                     ": no spectrum holds any valid value (all -1.23e34); nothing to import");

  // Bands kept: valid wavelength and valid in every kept spectrum; ascending wavelength order.
  std::vector<std::size_t> order;
  for (std::size_t b = 0; b < B; ++b) {
    bool ok = wl.values[b] > kUsgsMissingBelow;
    for (const auto& f : kept) ok = ok && f.values[b] > kUsgsMissingBelow;
    if (ok) order.push_back(b);
  }
  if (order.empty())
    throw InputError(spectra.front().string() +
                     ": no band is valid in every spectrum (missing -1.23e34 values "
                     "cover each band somewhere); import the spectra separately");
  if (order.size() < B)
    out.notes.push_back(spectra.front().string() + (kept.size() > 1 ? " and the others" : "") + ": dropped " +
                        std::to_string(B - order.size()) + " of " + std::to_string(B) +
                        " bands holding the missing marker -1.23e34");
  order = ascending_band_order(wl.values, std::move(order), [&](std::size_t, std::size_t second) {
    bad_line(wavelengths, second + 2, "wavelength " + num(wl.values[second]) + " appears twice; remove one of them");
  });
  std::vector<double> nm;
  for (const std::size_t b : order) nm.push_back(wl.values[b] * 1000.0);

  Collection& col = out.collection;
  col.wavelengths = WavelengthGrid(std::move(nm), wavelengths.string());
  col.names = std::move(names);
  col.values.reserve(kept.size() * order.size());
  for (const auto& f : kept)
    for (std::size_t b : order) col.values.push_back(static_cast<float>(f.values[b]));
  col.units = "reflectance";
  col.provenance.source_file = spectra.front().string();
  col.provenance.importer = "usgs-splib07 (wavelengths from " + wavelengths.filename().string() + ", micrometers->nm)";
  return out;
}

namespace {

struct EcoFile {
  std::string name;
  std::vector<double> nm;  // ascending
  std::vector<double> values;
  std::string y_kind;  // "reflectance", "transmittance", ...
  bool percent = false;
  bool micrometers = false;
};

EcoFile read_ecostress_file(const std::filesystem::path& p) {
  const auto lines = read_lines(p);
  EcoFile f;
  std::string x_units, y_units;
  std::size_t declared = 0, declared_line = 0;
  std::size_t i = 0;
  // Header: "Key: value" lines up to the first row that starts with a number, and at least through
  // "Additional Information:" (the last key) when present, so a wrapped Description line such as
  // "2 um fraction ..." is not taken for data.
  std::size_t header_end = 0;
  for (std::size_t k = 0; k < lines.size(); ++k)
    if (lower(trim(lines[k])).starts_with("additional information:")) {
      header_end = k + 1;
      break;
    }
  for (; i < lines.size(); ++i) {
    const auto t = trim(lines[i]);
    if (t.empty()) continue;
    double probe = 0;
    const auto first_token = t.substr(0, t.find_first_of(" \t,"));
    if (i >= header_end && parse_number(first_token, probe)) break;
    const auto colon = t.find(':');
    if (colon == std::string_view::npos) {
      if (i == 0) bad_line(p, 1, "\"" + printable(t) + "\" is not an ECOSTRESS header (it starts with \"Name:\")");
      continue;  // a wrapped Description line
    }
    const std::string key = lower(trim(t.substr(0, colon)));
    const std::string value(trim(t.substr(colon + 1)));
    if (i == 0 && key != "name")
      bad_line(p, 1, "\"" + printable(t) + "\" is not an ECOSTRESS header (it starts with \"Name:\")");
    if (key == "name")
      f.name = value;
    else if (key == "x units")
      x_units = value;
    else if (key == "y units")
      y_units = value;
    else if (key == "number of x values") {
      double d = 0;
      if (!parse_number(value, d) || d < 1 || d != std::floor(d) || d > 4294967295.0)
        bad_line(p, i + 1,
                 "Number of X Values = \"" + printable(value) + "\" is not a whole number from 1 to 2^32 - 1");
      declared = static_cast<std::size_t>(d);
      declared_line = i + 1;
    }
  }
  if (f.name.empty()) throw InputError(p.string() + ": no \"Name:\" line; an ECOSTRESS file starts with one");
  const std::string xu = lower(x_units), yu = lower(y_units);
  if (xu.find("wavelength") == std::string::npos)
    throw InputError(p.string() + ": X Units = \"" + printable(x_units) +
                     "\" is not a wavelength; only wavelength spectra (micrometers or nanometers) are read");
  if (xu.find("micrometer") != std::string::npos || xu.find("micron") != std::string::npos ||
      xu.find("\xC2\xB5m") != std::string::npos)
    f.micrometers = true;
  else if (xu.find("nanometer") == std::string::npos && xu.find("(nm)") == std::string::npos)
    throw InputError(p.string() + ": X Units = \"" + printable(x_units) +
                     "\" names no unit; write Wavelength (micrometers) or Wavelength (nanometers)");
  f.percent = yu.find("percent") != std::string::npos || yu.find('%') != std::string::npos;
  const auto paren = y_units.find('(');
  f.y_kind = lower(printable(trim(std::string_view(y_units).substr(0, paren))));  // it names the units and messages
  if (f.y_kind.empty()) f.y_kind = "unknown";

  std::vector<std::pair<double, double>> rows;
  std::vector<std::size_t> row_line;
  for (; i < lines.size(); ++i) {
    const auto t = trim(lines[i]);
    if (t.empty()) continue;
    std::string s(t);
    std::replace(s.begin(), s.end(), ',', ' ');
    std::replace(s.begin(), s.end(), '\t', ' ');
    std::istringstream in(s);
    std::string a, b, extra;
    in >> a >> b >> extra;
    double x = 0, y = 0;
    if (b.empty() || !extra.empty() || !parse_number(a, x) || !parse_number(b, y))
      bad_line(p, i + 1, "\"" + printable(t) + "\" is not a row of two numbers (wavelength value)");
    if (!(x > 0)) bad_line(p, i + 1, "wavelength " + num(x) + " is not positive");
    if (!fits_float(y))
      bad_line(p, i + 1, "value " + num(y) + " is beyond the float32 range of a store; fix the value");
    rows.emplace_back(x, y);
    row_line.push_back(i + 1);
  }
  if (rows.empty()) throw InputError(p.string() + ": header but no data rows; the file is truncated");
  if (declared != 0 && declared != rows.size())
    bad_line(p, declared_line,
             "Number of X Values says " + std::to_string(declared) + " but the file has " +
                 std::to_string(rows.size()) + " data rows" +
                 (rows.size() < declared ? "; the file is truncated" : "; fix the count"));
  std::vector<double> x;
  for (const auto& r : rows) x.push_back(r.first);
  const std::vector<std::size_t> order = ascending_band_order(x, [&](std::size_t, std::size_t second) {
    bad_line(p, row_line[second], "wavelength " + num(x[second]) + " appears twice; remove one of the rows");
  });
  const double xf = f.micrometers ? 1000.0 : 1.0, yd = f.percent ? 100.0 : 1.0;
  for (std::size_t k : order) {
    f.nm.push_back(rows[k].first * xf);
    f.values.push_back(rows[k].second / yd);
  }
  return f;
}

}  // namespace

TextLibrary read_ecostress_spectra(std::span<const std::filesystem::path> files) {
  if (files.empty()) throw UsageError("read_ecostress_spectra: no files given");
  TextLibrary out;
  Collection& col = out.collection;
  EcoFile first;
  for (std::size_t k = 0; k < files.size(); ++k) {
    EcoFile f = read_ecostress_file(files[k]);
    if (k == 0) {
      col.wavelengths = WavelengthGrid(f.nm, files[k].string());
      col.units = f.y_kind;
    } else {
      const auto describe = [](const std::vector<double>& nm) {
        return std::to_string(nm.size()) + " bands " + describe_nm(nm.front()) + " to " + describe_nm(nm.back());
      };
      if (f.nm != first.nm) {
        std::size_t at = 0;
        while (at < f.nm.size() && at < first.nm.size() && f.nm[at] == first.nm[at]) ++at;
        throw InputError(files[k].string() + ": its wavelengths (" + describe(f.nm) + ") differ from " +
                         files[0].string() + " (" + describe(first.nm) + ") from band " + std::to_string(at + 1) +
                         "; import files on different grids separately");
      }
      if (f.y_kind != first.y_kind || f.percent != first.percent)
        throw InputError(files[k].string() + ": Y Units (" + f.y_kind + (f.percent ? ", percent" : "") +
                         ") differ from " + files[0].string() + " (" + first.y_kind +
                         (first.percent ? ", percent" : "") + "); import them separately");
    }
    col.names.push_back(f.name);
    for (double v : f.values) col.values.push_back(static_cast<float>(v));
    if (k == 0) first = std::move(f);
  }
  col.provenance.source_file = files.front().string();
  std::string conv;
  if (first.micrometers) conv += "micrometers->nm";
  if (first.percent) conv += std::string(conv.empty() ? "" : ", ") + "percent->fraction";
  col.provenance.importer = "ecostress" + (conv.empty() ? std::string() : " (" + conv + ")");
  return out;
}

}  // namespace specula::store
