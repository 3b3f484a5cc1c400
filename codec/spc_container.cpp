// The .spc container: magic, version, CRC, the helpers both formats share, and the public entry points that
// dispatch to format 1 (spc_bounded.cpp), formats 2 and 3 (spc_transform.cpp) or format 4 (spc_samples.cpp).
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <fstream>
#include <iterator>

#include "specula/codec/spc.h"
#include "specula/codec/spc_detail.h"
#include "specula/core/atomic_file.h"
#include "specula/core/huge_pages.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace detail {

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes) {
  uLong crc = crc32(0L, Z_NULL, 0);
  for (std::size_t at = 0; at < bytes.size(); at += (1u << 30))
    crc = crc32(crc, bytes.data() + at, uInt(std::min<std::size_t>(1u << 30, bytes.size() - at)));
  return std::uint32_t(crc);
}

std::uint64_t magnitudes(const store::Grid& grid, std::vector<float>& mag, std::vector<std::uint8_t>& valid) {
  const std::size_t bands = grid.bands();
  mag.assign(kMerlCells, 0.0f);
  valid.assign(kMerlCells, 0);
  parallel_for(
      kMerlCells,
      [&](std::size_t c) {
        double m = 0;
        bool ok = true;
        for (std::size_t b = 0; b < bands; ++b) {
          const float v = grid.brdf[b * kMerlCells + c];
          if (!std::isfinite(v)) throw InputError("the grid holds a non-finite value; it cannot be coded");
          ok &= v >= 0;
          m += v;
        }
        valid[c] = ok;
        if (ok) mag[c] = float(m / double(bands));
      },
      kSlab);
  return std::uint64_t(std::count(valid.begin(), valid.end(), std::uint8_t(1)));
}

double magnitude_scale(const std::vector<float>& mag, const std::vector<std::uint8_t>& valid, double given) {
  if (given != 0) return given;
  std::vector<float> positive;
  for (std::size_t c = 0; c < kMerlCells; ++c)
    if (valid[c] && mag[c] > 0) positive.push_back(mag[c]);
  if (positive.empty()) return 1;
  std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(positive.size() / 2), positive.end());
  return 0.1 * double(positive[positive.size() / 2]);
}

std::pair<std::uint32_t, std::uint32_t> read_shape(Reader& r, const std::string& label) {
  const auto bands = r.get<std::uint32_t>("bands");
  const auto k = r.get<std::uint32_t>("k");
  if (bands < 1 || bands > kMaxBands) throw InputError(label + ": .spc header has " + std::to_string(bands) + " bands");
  if (k < 1 || k > bands)
    throw InputError(label + ": .spc header has k = " + std::to_string(k) + " for " + std::to_string(bands) + " bands");
  return {bands, k};
}

std::pair<double, double> read_scales(Reader& r, const std::string& label) {
  const double scale = r.get<double>("scale"), s = r.get<double>("magnitude scale");
  for (const auto& [v, what] : {std::pair{scale, "scale"}, std::pair{s, "magnitude scale"}})
    if (!(std::isfinite(v) && v > 0))
      throw InputError(label + ": .spc header field '" + what + "' is " + std::to_string(v) +
                       "; it must be finite and positive");
  return {scale, s};
}

void put_head(std::vector<std::uint8_t>& out, std::uint32_t version, std::size_t bands, std::size_t k, double scale,
              double s) {
  put_bytes(out, kSpcMagic, sizeof kSpcMagic);
  put(out, version);
  put(out, std::uint32_t(bands));
  put(out, std::uint32_t(k));
  put(out, scale);
  put(out, s);
}

void put_basis_and_labels(std::vector<std::uint8_t>& out, const SpcBasis& basis, std::size_t k, std::size_t bands,
                          const std::string& units, const std::string& source) {
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t b = 0; b < bands; ++b) put(out, float(basis.rows(Eigen::Index(j), Eigen::Index(b))));
  put_string(out, units);
  put_string(out, source);
  put_string(out, basis.reference);
}

WavelengthGrid checked_wavelengths(std::vector<double> wl, const std::string& label) {
  try {
    return WavelengthGrid(std::move(wl));
  } catch (const Error& e) {
    throw InputError(label + ": .spc wavelengths are invalid: " + e.what());
  }
}

std::uint32_t check_container(std::span<const std::uint8_t> bytes, const std::string& label) {
  if (bytes.size() < sizeof kSpcMagic + 4 || std::memcmp(bytes.data(), kSpcMagic, sizeof kSpcMagic) != 0)
    throw InputError(label + ": not a .spc file (it does not start with the SPECUSPC magic)");
  if (bytes.size() < 12 + 4)
    throw InputError(label + ": .spc file is truncated (" + std::to_string(bytes.size()) + " bytes)");
  // The CRC first: a corrupt byte anywhere is reported as such, not as whichever field it happens to hit.
  std::uint32_t stored;
  std::memcpy(&stored, bytes.data() + bytes.size() - 4, 4);
  uLong crc = crc32(0L, Z_NULL, 0);
  for (std::size_t at = 0; at < bytes.size() - 4; at += (1u << 30))
    crc = crc32(crc, bytes.data() + at, uInt(std::min<std::size_t>(1u << 30, bytes.size() - 4 - at)));
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic, "magic");
  const auto version = r.get<std::uint32_t>("version");
  if (version == 0 || version > kSpcVersion)
    throw InputError(label + ": .spc format version " + std::to_string(version) + "; this specula reads 1 to " +
                     std::to_string(kSpcVersion) + (version > kSpcVersion ? " (upgrade specula)" : ""));
  if (std::uint32_t(crc) != stored)
    throw InputError(label + ": .spc file is corrupt: CRC-32 " + std::to_string(std::uint32_t(crc)) + " of its " +
                     std::to_string(bytes.size() - 4) + " bytes, the file says " + std::to_string(stored) +
                     " (truncated or damaged)");
  return version;
}

}  // namespace detail

using detail::kMerlCells;
using detail::kSlab;

std::uint32_t spc_format_version(std::span<const std::uint8_t> bytes, const std::string& label) {
  return detail::check_container(bytes, label);
}

SpcBasis spc_basis(std::span<const std::uint8_t> bytes, const std::string& label) {
  const std::uint32_t version = detail::check_container(bytes, label);
  const SpcCoefficients c = version == 4   ? detail::decode_samples(bytes, label, true)
                            : version >= 2 ? detail::decode_transform(bytes, label, true)
                                           : detail::decode_bounded(bytes, label, true);
  return {c.wavelengths, c.basis, c.reference};
}

SpcCoefficients decode_spc_coefficients(std::span<const std::uint8_t> bytes, const std::string& label) {
  const std::uint32_t version = detail::check_container(bytes, label);
  if (version == 4) return detail::decode_samples(bytes, label, false);
  if (version >= 2) return detail::decode_transform(bytes, label, false);
  return detail::decode_bounded(bytes, label, false);
}

std::vector<std::uint8_t> encode_spc(const store::Grid& grid, const SpcBasis& basis, const SpcBoundedOptions& o,
                                     SpcReport* report, const std::string& source) {
  return detail::encode_bounded(grid, basis, o, report, source);
}

std::vector<std::uint8_t> encode_spc(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o,
                                     SpcReport* report, const std::string& source) {
  return detail::encode_transform(grid, basis, o, report, source);
}

store::Grid expand_spc(const SpcCoefficients& c) {
  store::Grid g;
  expand_spc(c, g);
  return g;
}

void expand_spc(const SpcCoefficients& c, store::Grid& g) {
  const std::size_t k = c.k(), bands = c.bands();
  if (c.values.size() != k * kMerlCells || c.valid.size() != kMerlCells)
    throw UsageError("expand_spc: coefficients do not match k x 90 x 90 x 180 cells");
  g = store::Grid{.wavelengths = c.wavelengths, .scale = c.scale, .brdf = std::move(g.brdf), .units = c.units};
  g.provenance.source_file = c.source;
  g.provenance.importer = "decode " + c.reference;
  const std::size_t n = bands * kMerlCells;
  if (g.brdf.capacity() < n) {  // fresh memory on 2 MB pages: zeroing it then faults 90 times, not 44 000
    g.brdf = {};
    g.brdf.reserve(n);
    advise_huge_pages(g.brdf.data(), n * sizeof(float));
  }
  g.brdf.resize(n);  // every value is written below
  parallel_for(
      kMerlCells,
      [&](std::size_t cell) {
        if (c.valid[cell])
          detail::expand_cell(c.basis, c.values.data() + cell * k, g.brdf.data() + cell, kMerlCells);
        else
          for (std::size_t b = 0; b < bands; ++b) g.brdf[b * kMerlCells + cell] = -1.0f;
      },
      kSlab);
}

store::Grid decode_spc(std::span<const std::uint8_t> bytes, const std::string& label) {
  return expand_spc(decode_spc_coefficients(bytes, label));
}

void write_spc_file(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!f) throw LibraryError(path.string() + ": cannot write");
  }
  out.commit();
}

std::vector<std::uint8_t> read_spc_file(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path.string() + ": cannot open (" + std::strerror(errno) + ")");
  std::error_code ec;
  if (const auto size = std::filesystem::file_size(path, ec); !ec && size > (std::uintmax_t(1) << 32))
    throw InputError(path.string() + ": " + std::to_string(size) + " bytes is far more than any .spc file holds");
  std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return b;
}

}  // namespace specula::codec
