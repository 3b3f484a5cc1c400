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
namespace {

using namespace envi_detail;

constexpr double kWriteIgnoreValue = -9999.0;

const char* interleave_name(Interleave il) {
  switch (il) {
    case Interleave::bsq:
      return "bsq";
    case Interleave::bil:
      return "bil";
    case Interleave::bip:
      return "bip";
  }
  return "bsq";
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
  if (!f)
    throw LibraryError(target.string() + ": cannot create " + out.temp_path().string() + ": " + std::strerror(errno));
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

}  // namespace

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
         "\nheader offset = 0\nfile type = ENVI Standard\ndata type = 4\ninterleave = " + interleave_name(interleave) +
         "\nbyte order = 0\n";
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
