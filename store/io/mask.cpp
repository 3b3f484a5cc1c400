#include "specula/store/io/mask.h"

#include <array>
#include <fstream>
#include <sstream>
#include <string>

#include "specula/core/error.h"
#include "specula/store/io/envi.h"
#include "specula/store/io/png_stack.h"

namespace specula::store {
namespace {

// The ENVI header of `path` (itself, or the .hdr beside its data file), or empty when there is none.
std::filesystem::path envi_header(const std::filesystem::path& path) {
  if (path.extension() == ".hdr") return path;
  std::filesystem::path beside = path;
  beside.replace_extension(".hdr");
  if (std::filesystem::is_regular_file(beside)) return beside;
  const std::filesystem::path appended = path.string() + ".hdr";
  if (std::filesystem::is_regular_file(appended)) return appended;
  return {};
}

bool png_signature(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::array<char, 8> sig{};
  return in.read(sig.data(), 8) && std::string(sig.data(), 8) == "\x89PNG\r\n\x1a\n";
}

// Rows of 1 (valid) and 0 from the first channel of a PNG.
Mask png_mask(const std::filesystem::path& path) {
  const PngImage png = read_png(path);
  Mask m;
  m.width = png.width;
  m.height = png.height;
  m.valid.resize(png.width * png.height);
  for (std::size_t p = 0; p < m.valid.size(); ++p) m.valid[p] = png.samples[p * png.channels] != 0;
  return m;
}

// A one-band ENVI image whose header is `hdr`: nonzero pixels not at the data ignore value are valid.
Mask envi_mask(const std::filesystem::path& path, const std::filesystem::path& hdr) {
  std::ifstream in(hdr);
  std::stringstream text;
  text << in.rdbuf();
  const EnviHeader h = parse_envi_header(text.str(), hdr.string());
  if (h.bands != 1)
    throw InputError(hdr.string() + ": a mask has one band, this ENVI image has " + std::to_string(h.bands));
  const Cube c = read_envi(path, WavelengthGrid(std::vector<double>{1.0}, hdr.string()));
  Mask m;
  m.width = c.width;
  m.height = c.height;
  m.valid.resize(c.width * c.height);
  for (std::size_t p = 0; p < m.valid.size(); ++p) m.valid[p] = c.valid(p / c.width, p % c.width) && c.data[p] != 0.0f;
  return m;
}

}  // namespace

Mask read_mask(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(path.string() + ": mask file not found");
  // What the file says it is decides before any header that happens to lie beside it (m.png next to m.hdr).
  if (path.extension() != ".hdr" && (png_signature(path) || path.extension() == ".png")) return png_mask(path);
  if (const std::filesystem::path hdr = envi_header(path); !hdr.empty()) return envi_mask(path, hdr);
  throw InputError(path.string() +
                   ": a mask is a PNG or a one-band ENVI image, and this is neither (no .hdr beside it)");
}

}  // namespace specula::store
