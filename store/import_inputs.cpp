// What the importer reads: the format a file's extension (or a .txt's first lines) names, and the inputs (files,
// directories, glob patterns) expanded into the files to import and the lines of what was skipped.
#include "specula/store/import.h"

#include <glob.h>

#include <algorithm>
#include <string>
#include <system_error>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/text.h"
#include "specula/store/detail/import_paths.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/text_library.h"

namespace specula::store {

std::string detect_import_format(const std::filesystem::path& p) {
  if (std::filesystem::is_directory(p)) return "png";
  const std::string ext = lower(p.extension().string());
  if (ext == ".hdr" || ext == ".raw" || ext == ".img" || ext == ".dat" || ext == ".bsq" || ext == ".bil" ||
      ext == ".bip" || ext == ".sli")
    return "envi";  // an ENVI Spectral Library among them is told by its header (file type)
  if (ext == ".mat") return "mat";
  if (ext == ".png") return "png";
  if (ext == ".exr") return "exr";
  if (ext == ".csv") return "csv";
  if (ext == ".brdf") return "brdf";
  if (ext == ".tif" || ext == ".tiff") return "gdal";
  if (ext == ".txt") {
    const std::string kind = sniff_text_library(p);
    if (kind == "usgs" || kind == "usgs-wavelengths") return "usgs";
    if (kind == "ecostress") return "ecostress";
    throw UsageError(
        p.string() +
        ": a .txt that is neither a USGS splib07a spectrum (title \"splib07a Record=...\") "
        "nor an ECOSTRESS spectrum (first line \"Name: ...\"); give the `format` option (usgs, ecostress or csv)");
  }
  throw UsageError(p.string() + ": cannot tell the format from the extension '" + ext +
                   "'; give the `format` option (envi, mat, png, exr, csv, brdf, usgs, ecostress or gdal)");
}

namespace import_detail {

std::filesystem::path envi_header_of(const std::filesystem::path& p) {
  std::error_code ec;
  for (auto h : {std::filesystem::path(p).replace_extension(".hdr"), std::filesystem::path(p.string() + ".hdr")})
    if (std::filesystem::is_regular_file(h, ec)) return h;
  return {};
}

std::vector<std::filesystem::directory_entry> sorted_entries(const std::filesystem::path& dir) {
  std::vector<std::filesystem::directory_entry> out;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) out.push_back(*it);
  if (ec) throw InputError(dir.string() + ": cannot list the directory: " + ec.message());
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.path() < b.path(); });
  return out;
}

}  // namespace import_detail

using namespace import_detail;

namespace {

// glob(3) through one checked call: the sorted matches of `pattern` (empty when none).
std::vector<std::filesystem::path> glob_paths(const std::string& pattern) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), GLOB_ERR, nullptr, &g);
  std::vector<std::filesystem::path> out;
  if (rc == 0)
    for (std::size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
  globfree(&g);
  if (rc == GLOB_NOSPACE) throw LibraryError(pattern + ": glob ran out of memory");
  if (rc == GLOB_ABORTED) throw InputError(pattern + ": glob could not read a directory on the way (permissions?)");
  if (rc != 0 && rc != GLOB_NOMATCH) throw LibraryError(pattern + ": glob failed with code " + std::to_string(rc));
  return out;
}

bool is_pattern(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

bool is_envi_data_ext(const std::string& ext) {
  return ext == ".raw" || ext == ".img" || ext == ".dat" || ext == ".bsq" || ext == ".bil" || ext == ".bip" ||
         ext == ".sli";
}

class Expander {
 public:
  explicit Expander(const ImportOptions& o) : o_(o) {}
  ImportInputs out;

  // A file found in a directory or by a pattern: imported when recognised, else a skip line.
  void found(const std::filesystem::path& p) {
    std::error_code ec;
    if (std::filesystem::is_directory(p, ec)) return directory(p);
    if (!o_.mask.empty() && std::filesystem::equivalent(p, o_.mask, ec))
      return skip(p, "the mask given by the `mask` option");
    const std::string ext = lower(p.extension().string());
    if (is_envi_data_ext(ext) && o_.format == "auto") {
      if (!envi_header_of(p).empty()) return;  // imported through its .hdr
      return skip(p, "an ENVI data file without its .hdr header");
    }
    if (ext == ".png" && o_.format == "auto")
      return skip(p,
                  "a PNG outside a band-stack directory (a directory whose only recognised files are PNGs is one "
                  "stack; or name the PNGs of one stack together)");
    std::string format;
    try {
      format = detect_import_format(p);
    } catch (const UsageError& e) {
      if (o_.format != "auto") return out.files.push_back(p);  // the `format` option reads what has no known format
      return skip(p, std::string(e.what()).substr(p.string().size() + 2));
    }
    if (o_.format != "auto" && format != o_.format)
      return skip(p, "a " + format + " file, not the `format` option's " + o_.format);
    out.files.push_back(p);
  }

  void directory(const std::filesystem::path& dir) {
    const auto entries = sorted_entries(dir);
    bool png = false, other = false;
    for (const auto& e : entries) {
      std::error_code ec;
      if (!e.is_regular_file(ec)) continue;
      const std::string ext = lower(e.path().extension().string());
      if (ext == ".png") {
        png = true;
      } else {
        try {
          detect_import_format(e.path());
          other = true;
        } catch (const UsageError&) {}
      }
    }
    if (png && !other && o_.format == "auto") {
      out.files.push_back(dir);  // a band stack (CAVE): its PNGs; the rest is reported
      for (const auto& e : entries)
        if (lower(e.path().extension().string()) != ".png")
          skip(e.path(), std::string("not a PNG in the band-stack directory ") + dir.string());
      return;
    }
    for (const auto& e : entries) found(e.path());
  }

  void input(const std::filesystem::path& in) {
    std::error_code ec;
    if (!std::filesystem::exists(in, ec) && is_pattern(in.string())) {
      const auto matches = glob_paths(in.string());
      if (matches.empty())
        throw InputError(in.string() + ": no file matches this pattern; check it (specula expands quoted patterns)");
      for (const auto& m : matches) {
        if (o_.format == "auto" && lower(m.extension().string()) == ".png" && std::filesystem::is_regular_file(m, ec))
          out.files.push_back(m);  // the PNGs of one pattern are named together: a band stack, as the shell's would be
        else
          found(m);
      }
    } else if (std::filesystem::is_directory(in, ec)) {
      directory(in);
    } else {
      out.files.push_back(in);  // named: read, or an error naming it
    }
  }

 private:
  void skip(const std::filesystem::path& p, const std::string& why) {
    out.skipped.push_back(p.string() + ": skipped: " + why);
  }
  const ImportOptions& o_;
};

}  // namespace

ImportInputs expand_import_inputs(const std::vector<std::filesystem::path>& inputs, const ImportOptions& options) {
  Expander e(options);
  for (const auto& in : inputs) e.input(in);
  return std::move(e.out);
}

}  // namespace specula::store
