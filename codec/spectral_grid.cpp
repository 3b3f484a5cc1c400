#include "specula/codec/spectral_grid.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "specula/codec/grid_files.h"
#include "specula/core/atomic_file.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::codec {
namespace {

static_assert(std::endian::native == std::endian::little, "exchange files are little-endian; add byte swapping here");

constexpr std::size_t kHeaderBytes = 40;

template <class T>
T get(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <class T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}

// zlib's crc32 takes at most 4 GiB per call; feed it in 1 GiB pieces.
uLong crc_update(uLong crc, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t done = 0; done < n;) {
    const auto step = unsigned(std::min<std::size_t>(n - done, 1u << 30));
    crc = crc32(crc, p + done, step);
    done += step;
  }
  return crc;
}

class CrcWriter {
 public:
  explicit CrcWriter(std::ofstream& f) : f_(f) {}
  void write(const void* data, std::size_t n) {
    crc_ = crc_update(crc_, data, n);
    f_.write(static_cast<const char*>(data), std::streamsize(n));
  }
  uLong crc() const { return crc_; }

 private:
  std::ofstream& f_;
  uLong crc_ = crc32(0L, Z_NULL, 0);
};

}  // namespace

std::uint64_t grid_file_bytes(std::size_t bands) {
  return kHeaderBytes + 8 * std::uint64_t(bands) + 4 * std::uint64_t(bands) * brdf::kMerlCells + 4;
}

namespace {

// The exchange file of grid, written to `to` (a temporary; `path` names it in messages).
void write_grid_to(const std::filesystem::path& path, const std::filesystem::path& to, const store::Grid& grid) {
  const std::size_t b = grid.bands();
  std::string header(kGridMagic, sizeof kGridMagic);
  put<std::uint32_t>(header, kGridFileVersion);
  put<std::uint32_t>(header, std::uint32_t(b));
  put<std::uint32_t>(header, brdf::kMerlThetaH);
  put<std::uint32_t>(header, brdf::kMerlThetaD);
  put<std::uint32_t>(header, brdf::kMerlPhiD);
  put<std::uint32_t>(header, 0);
  put<double>(header, grid.scale);
  for (double nm : grid.wavelengths.values()) put<double>(header, nm);
  std::ofstream f(to, std::ios::binary | std::ios::trunc);
  if (!f) throw LibraryError(to.string() + ": cannot create (" + std::strerror(errno) + ") for " + path.string());
  CrcWriter w(f);
  w.write(header.data(), header.size());
  w.write(grid.brdf.data(), grid.brdf.size() * sizeof(float));
  const auto crc = std::uint32_t(w.crc());
  f.write(reinterpret_cast<const char*>(&crc), sizeof crc);
  f.flush();
  if (!f) throw LibraryError(to.string() + ": cannot write (" + std::strerror(errno) + ") for " + path.string());
}

void check_grid(const std::filesystem::path& path, const store::Grid& grid) {
  const std::size_t b = grid.bands();
  if (b == 0 || b > kGridMaxBands || grid.brdf.size() != b * brdf::kMerlCells)
    throw UsageError(path.string() + ": a grid needs 1-" + std::to_string(kGridMaxBands) +
                     " bands and bands x 90 x 90 x 180 values (" + std::to_string(b) + " bands, " +
                     std::to_string(grid.brdf.size()) + " values)");
  if (!std::isfinite(grid.scale) || grid.scale <= 0)
    throw UsageError(path.string() + ": grid scale " + num(grid.scale) + " must be finite and positive");
}

}  // namespace

void write_grid_file(const std::filesystem::path& path, const store::Grid& grid) {
  const std::pair<std::filesystem::path, const store::Grid*> one[] = {{path, &grid}};
  write_grid_files(one);
}

void write_grid_files(std::span<const std::pair<std::filesystem::path, const store::Grid*>> files) {
  for (const auto& [path, grid] : files) check_grid(path, *grid);
  std::vector<std::unique_ptr<AtomicOutput>> outs;
  for (const auto& [path, grid] : files) {
    outs.push_back(std::make_unique<AtomicOutput>(path));
    write_grid_to(path, outs.back()->temp_path(), *grid);
  }
  std::vector<std::filesystem::path> renamed;  // the last file first, so that the first appears last
  try {
    for (std::size_t i = outs.size(); i-- > 0;) {
      outs[i]->commit();
      renamed.push_back(outs[i]->target());
    }
  } catch (...) {
    std::error_code ec;
    for (const auto& p : renamed) std::filesystem::remove(p, ec);
    throw;
  }
}

store::Grid read_grid_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(name + ": is a directory, not a spectral grid file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name + ": cannot open (" + std::strerror(errno) + ")");
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  unsigned char h[kHeaderBytes];
  if (size < kHeaderBytes || !in.read(reinterpret_cast<char*>(h), kHeaderBytes))
    throw InputError(name + ": truncated spectral grid: " + std::to_string(size) + " bytes, shorter than the " +
                     std::to_string(kHeaderBytes) + "-byte header");
  if (std::memcmp(h, kGridMagic, sizeof kGridMagic) != 0)
    throw InputError(
        name + ": not a specula spectral grid (the file does not begin with \"SPECGRID\"; see docs/grid-format.md)");
  const auto version = get<std::uint32_t>(h + 8), bands = get<std::uint32_t>(h + 12);
  if (version == 0 || version > kGridFileVersion)
    throw InputError(name + ": spectral grid version " + std::to_string(version) +
                     " is not one this specula reads (up to " + std::to_string(kGridFileVersion) +
                     "); upgrade specula");
  if (bands == 0 || bands > kGridMaxBands)
    throw InputError(name + ": spectral grid declares " + std::to_string(bands) + " bands; expected 1-" +
                     std::to_string(kGridMaxBands));
  const auto nh = get<std::uint32_t>(h + 16), nd = get<std::uint32_t>(h + 20), np = get<std::uint32_t>(h + 24);
  if (nh != brdf::kMerlThetaH || nd != brdf::kMerlThetaD || np != brdf::kMerlPhiD)
    throw InputError(name + ": spectral grid dimensions " + std::to_string(nh) + " x " + std::to_string(nd) + " x " +
                     std::to_string(np) + "; expected the MERL layout 90 x 90 x 180");
  if (get<std::uint32_t>(h + 28) != 0)
    throw InputError(name + ": spectral grid flags are " + std::to_string(get<std::uint32_t>(h + 28)) +
                     "; version 1 defines none (expected 0)");
  store::Grid grid;
  grid.scale = get<double>(h + 32);
  if (!std::isfinite(grid.scale) || grid.scale <= 0)
    throw InputError(name + ": spectral grid scale is " + num(grid.scale) + "; it must be finite and positive");
  const std::uint64_t expected = grid_file_bytes(bands);
  if (size != expected)
    throw InputError(name + ": " + (size < expected ? "truncated" : "oversized") +
                     " spectral grid: " + std::to_string(size) + " bytes, expected " + std::to_string(expected) +
                     " for " + std::to_string(bands) + " bands");
  std::vector<double> nm(bands);
  grid.brdf.resize(std::size_t(bands) * brdf::kMerlCells);
  std::uint32_t stored_crc = 0;
  in.read(reinterpret_cast<char*>(nm.data()), std::streamsize(nm.size() * sizeof(double)));
  in.read(reinterpret_cast<char*>(grid.brdf.data()), std::streamsize(grid.brdf.size() * sizeof(float)));
  in.read(reinterpret_cast<char*>(&stored_crc), sizeof stored_crc);
  if (!in) throw InputError(name + ": read error (" + std::strerror(errno) + ")");
  uLong crc = crc_update(crc32(0L, Z_NULL, 0), h, kHeaderBytes);
  crc = crc_update(crc, nm.data(), nm.size() * sizeof(double));
  crc = crc_update(crc, grid.brdf.data(), grid.brdf.size() * sizeof(float));
  if (std::uint32_t(crc) != stored_crc)
    throw InputError(name + ": spectral grid is corrupt: CRC-32 " + std::to_string(std::uint32_t(crc)) +
                     " of the contents does not match the stored " + std::to_string(stored_crc));
  grid.wavelengths = WavelengthGrid(std::move(nm), name + ": wavelengths");
  for (std::size_t i = 0; i < grid.brdf.size(); ++i)
    if (!std::isfinite(grid.brdf[i]))
      throw InputError(name + ": non-finite value at band " + std::to_string(i / brdf::kMerlCells) + ", cell " +
                       std::to_string(i % brdf::kMerlCells) + " (negative means no data; NaN is not allowed)");
  grid.provenance.source_file = name;
  grid.provenance.importer = "grid-file";
  return grid;
}

Eigen::Matrix<double, 3, Eigen::Dynamic> rgb_weights(const WavelengthGrid& grid, const Eigen::VectorXd& illuminant,
                                                     Observer observer) {
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant, observer);
  const Eigen::Matrix3d m = xyz_to_linear_srgb();
  const Eigen::Vector3d srgb_white = m.inverse() * Eigen::Vector3d::Ones();
  return m * bradford_adaptation(conv.white(), srgb_white) * conv.weights();
}

RgbExport grid_to_merl(const store::Grid& grid, const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights) {
  const std::size_t b = grid.bands();
  if (std::size_t(weights.cols()) != b || grid.brdf.size() != b * brdf::kMerlCells)
    throw UsageError("grid_to_merl: weights have " + std::to_string(weights.cols()) + " columns for a grid of " +
                     std::to_string(b) + " bands and " + std::to_string(grid.brdf.size()) + " values");
  RgbExport out;
  Eigen::VectorXd s = Eigen::VectorXd::Zero(Eigen::Index(b));
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    bool data = true;
    for (std::size_t k = 0; k < b && data; ++k) {
      const float v = grid.brdf[k * brdf::kMerlCells + cell];
      data = v >= 0;
      s[Eigen::Index(k)] = double(v) * grid.scale;
    }
    if (!data) continue;  // MerlBrdf starts as no data (-1) everywhere
    Eigen::Vector3d rgb = weights * s;
    for (int c = 0; c < 3; ++c)
      if (rgb[c] < 0) {
        rgb[c] = 0;
        ++out.clamped;
      }
    out.brdf.set(cell, rgb);
  }
  return out;
}

}  // namespace specula::codec
