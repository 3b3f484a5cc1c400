#include "specula/codec/merl.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::codec {
namespace {

static_assert(std::endian::native == std::endian::little, "MERL files are little-endian; add byte swapping here");

constexpr const char* kChannel[3] = {"red", "green", "blue"};

std::string cell_text(std::size_t cell) {
  const brdf::MerlCell c = brdf::merl_cell(cell);
  return "cell " + std::to_string(cell) + " (theta_h " + std::to_string(c.theta_h) + ", theta_d " +
         std::to_string(c.theta_d) + ", phi_d " + std::to_string(c.phi_d) + ")";
}

}  // namespace

void MerlBrdf::set(std::size_t cell, const Eigen::Vector3d& rgb) {
  for (int c = 0; c < 3; ++c) raw[std::size_t(c) * brdf::kMerlCells + cell] = rgb[c] / kMerlScale[std::size_t(c)];
}

void MerlBrdf::scale() {
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < brdf::kMerlCells; ++i)
      if (double& v = raw[c * brdf::kMerlCells + i]; v >= 0) v *= kMerlScale[c];
}

void MerlBrdf::unscale() {
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < brdf::kMerlCells; ++i)
      if (double& v = raw[c * brdf::kMerlCells + i]; v >= 0) v /= kMerlScale[c];
}

bool MerlBrdf::has_data(std::size_t cell) const {
  return stored(0, cell) >= 0 && stored(1, cell) >= 0 && stored(2, cell) >= 0;
}

Eigen::Vector3d MerlBrdf::lookup(const brdf::StdAngles& a) const {
  if (!std::isfinite(a.theta_i) || !std::isfinite(a.phi_i) || !std::isfinite(a.theta_o) || !std::isfinite(a.phi_o))
    throw UsageError("MERL lookup: angles (" + num(a.theta_i) + ", " + num(a.phi_i) + ", " + num(a.theta_o) + ", " +
                     num(a.phi_o) + ") must be finite radians");
  const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
  return {value(0, cell), value(1, cell), value(2, cell)};
}

MerlBrdf read_merl(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(name + ": is a directory, not a MERL .binary BRDF");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name + ": cannot open (" + std::strerror(errno) + ")");
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  const std::string expected =
      std::to_string(kMerlFileBytes) + " bytes (12-byte header + 3 x 90 x 90 x 180 float64, the MERL layout)";
  if (size < 12)
    throw InputError(name + ": truncated MERL BRDF: " + std::to_string(size) + " bytes, expected " + expected);
  std::int32_t dims[3];
  in.read(reinterpret_cast<char*>(dims), sizeof dims);
  if (dims[0] != brdf::kMerlThetaH || dims[1] != brdf::kMerlThetaD || dims[2] != brdf::kMerlPhiD)
    throw InputError(name + ": not a MERL BRDF: header dimensions " + std::to_string(dims[0]) + " x " +
                     std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
                     ", expected 90 x 90 x 180 (the file has " + std::to_string(size) + " bytes, expected " + expected +
                     ")");
  if (size != kMerlFileBytes)
    throw InputError(name + ": " + (size < kMerlFileBytes ? "truncated" : "oversized") +
                     " MERL BRDF: " + std::to_string(size) + " bytes, expected " + expected);
  MerlBrdf b;
  in.read(reinterpret_cast<char*>(b.raw.data()), std::streamsize(b.raw.size() * sizeof(double)));
  if (!in) throw InputError(name + ": read error after the header (" + std::strerror(errno) + ")");
  for (std::size_t i = 0; i < b.raw.size(); ++i)
    if (!std::isfinite(b.raw[i]))
      throw InputError(name + ": " + num(b.raw[i]) + " in the " + kChannel[i / brdf::kMerlCells] + " plane at " +
                       cell_text(i % brdf::kMerlCells) + "; MERL files hold finite values (negative = no data)");
  return b;
}

void write_merl(const std::filesystem::path& path, const MerlBrdf& b) {
  if (b.raw.size() != 3 * brdf::kMerlCells)
    throw UsageError(path.string() + ": a MERL BRDF holds 3 x 90 x 90 x 180 values, not " +
                     std::to_string(b.raw.size()));
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary | std::ios::trunc);
    if (!f) throw LibraryError(out.temp_path().string() + ": cannot create (" + std::strerror(errno) + ")");
    const std::int32_t dims[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};
    f.write(reinterpret_cast<const char*>(dims), sizeof dims);
    f.write(reinterpret_cast<const char*>(b.raw.data()), std::streamsize(b.raw.size() * sizeof(double)));
    f.flush();
    if (!f) throw LibraryError(out.temp_path().string() + ": cannot write (" + std::strerror(errno) + ")");
  }
  out.commit();
}

}  // namespace specula::codec
