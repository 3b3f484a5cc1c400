#include "specula/codec/spc.h"

#include <zlib.h>
#include <zstd.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cerrno>
#include <iterator>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <array>

#include "specula/codec/cube_coder.h"
#include "specula/codec/diff.h"
#include "specula/codec/environment.h"
#include "specula/codec/wavelet.h"
#include "specula/core/atomic_file.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

using brdf::kMerlCells;
using brdf::kMerlPhiD;
using brdf::kMerlThetaD;
using brdf::kMerlThetaH;
constexpr std::size_t kSlab = std::size_t(kMerlThetaD) * kMerlPhiD;  // cells per theta_h index
constexpr std::uint32_t kMaxBands = 1024;
constexpr std::uint32_t kMaxString = 1 << 16;

void put_bytes(std::vector<std::uint8_t>& out, const void* p, std::size_t n) {
  const std::size_t at = out.size();
  out.resize(at + n);  // resize and copy: GCC 12 warns falsely (-Wstringop-overflow) on a growing range insert
  if (n) std::memcpy(out.data() + at, p, n);
}
template <class T>
void put(std::vector<std::uint8_t>& out, T v) {
  put_bytes(out, &v, sizeof v);  // little-endian hosts only (checked below)
}
void put_string(std::vector<std::uint8_t>& out, const std::string& s) {
  put(out, std::uint32_t(std::min<std::size_t>(s.size(), kMaxString)));
  put_bytes(out, s.data(), std::min<std::size_t>(s.size(), kMaxString));
}
static_assert(std::endian::native == std::endian::little, ".spc I/O assumes a little-endian host");

class Reader {
 public:
  Reader(std::span<const std::uint8_t> b, const std::string& label) : b_(b), label_(label) {}
  template <class T>
  T get(const char* what) {
    T v;
    std::memcpy(&v, take(sizeof v, what), sizeof v);
    return v;
  }
  const std::uint8_t* take(std::size_t n, const char* what) {
    if (n > b_.size() - at_)
      throw InputError(label_ + ": .spc file is truncated: " + what + " needs " + std::to_string(n) + " bytes at byte " +
                       std::to_string(at_) + ", " + std::to_string(b_.size() - at_) + " remain");
    const std::uint8_t* p = b_.data() + at_;
    at_ += n;
    return p;
  }
  std::string string(const char* what) {
    const auto n = get<std::uint32_t>(what);
    if (n > kMaxString) throw InputError(label_ + ": .spc field " + what + " claims " + std::to_string(n) + " bytes");
    const auto* p = take(n, what);
    return {reinterpret_cast<const char*>(p), n};
  }
  std::size_t at() const { return at_; }

 private:
  std::span<const std::uint8_t> b_;
  const std::string& label_;
  std::size_t at_ = 0;
};

// Predicted code of cell (d, p) of one theta_h slab from its already-coded neighbours along phi_d and
// theta_d: the plane through three of them when all are valid, else the nearest valid one, else 0.
inline std::int64_t predict(const std::int32_t* q, const std::uint8_t* valid, std::size_t d, std::size_t p) {
  const std::size_t i = d * kMerlPhiD + p;
  const bool a = p > 0 && valid[i - 1], b = d > 0 && valid[i - kMerlPhiD], c = p > 0 && d > 0 && valid[i - kMerlPhiD - 1];
  if (a && b && c) return std::int64_t(q[i - 1]) + q[i - kMerlPhiD] - q[i - kMerlPhiD - 1];
  if (a) return q[i - 1];
  if (b) return q[i - kMerlPhiD];
  return 0;
}

// The coded quantities of one file: everything decode and the encoder's error measurement share.
struct Coding {
  std::size_t bands = 0, k = 0;
  double scale = 1, s = 1, step_m = 1, step_c = 1;
  Eigen::MatrixXd basis;  // k x B
};

// The coefficient form of one cell, a_j = m' c'_j in float (SpcCoefficients), from its codes.
inline void coefficients(const Coding& cd, std::int64_t qm, const std::int32_t* qc, std::size_t stride, float* a) {
  const double m = cd.s * std::expm1(double(qm) * cd.step_m);
  for (std::size_t j = 0; j < cd.k; ++j) a[j] = float(m * (double(qc[j * stride]) * cd.step_c));
}

// x'_b = max(0, sum_j a_j V_jb): negatives clipped to 0, since a negative value would read as "no data".
inline void expand_cell(const Eigen::MatrixXd& basis, const float* a, float* out, std::size_t out_stride) {
  const auto k = basis.rows(), bands = basis.cols();
  for (Eigen::Index b = 0; b < bands; ++b) {
    double x = 0;
    for (Eigen::Index j = 0; j < k; ++j) x += double(a[j]) * basis(j, b);
    out[std::size_t(b) * out_stride] = float(std::max(0.0, x));
  }
}

std::vector<std::uint8_t> zstd_compress(const std::vector<std::uint8_t>& raw, int level) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(raw.size()));
  const std::size_t n = ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), level);
  if (ZSTD_isError(n)) throw LibraryError(std::string("zstd: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

void zstd_decompress(const std::uint8_t* src, std::size_t size, std::vector<std::uint8_t>& out, const std::string& label,
                     const char* what) {
  const unsigned long long content = ZSTD_getFrameContentSize(src, size);
  if (content != out.size())
    throw InputError(label + ": .spc section " + what + " is corrupt: its zstd frame holds " +
                     (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN ? std::string("an unknown size")
                                                                                                 : std::to_string(content)) +
                     " bytes, the header says " + std::to_string(out.size()));
  const std::size_t n = ZSTD_decompress(out.data(), out.size(), src, size);
  if (ZSTD_isError(n) || n != out.size())
    throw InputError(label + ": .spc section " + what + " is corrupt: " +
                     (ZSTD_isError(n) ? std::string(ZSTD_getErrorName(n)) : "short frame"));
}

// Residuals of one channel as 1 (int8), 2 (int16) or 4 (int32) bytes, split into byte planes so zstd sees the
// small low bytes together.
std::vector<std::uint8_t> planes(const std::vector<std::int32_t>& r, std::uint8_t& width) {
  std::int32_t lo = 0, hi = 0;
  for (const auto v : r) lo = std::min(lo, v), hi = std::max(hi, v);
  width = lo >= -128 && hi <= 127 ? 1 : lo >= -32768 && hi <= 32767 ? 2 : 4;
  std::vector<std::uint8_t> out(r.size() * width);
  for (std::size_t i = 0; i < r.size(); ++i) {
    const auto u = std::uint32_t(r[i]);
    for (std::size_t w = 0; w < width; ++w) out[w * r.size() + i] = std::uint8_t(u >> (8 * w));
  }
  return out;
}

std::int32_t unplane(const std::uint8_t* p, std::size_t n, std::uint8_t width, std::size_t i) {
  std::uint32_t u = 0;
  for (std::size_t w = 0; w < width; ++w) u |= std::uint32_t(p[w * n + i]) << (8 * w);
  if (width < 4 && (u >> (8 * width - 1)) & 1u) u |= ~0u << (8 * width);  // sign-extend
  return std::int32_t(u);
}

std::int32_t to_code(double v, const std::string& what) {
  const double r = std::nearbyint(v);
  if (!(std::abs(r) < 2e9)) throw UsageError("encode: " + what + " needs a code of " + std::to_string(r) +
                                             ", beyond 32 bits; raise max_error");
  return std::int32_t(r);
}

// Per cell whether it has data (every band >= 0) and its magnitude, the band mean (0 without data); InputError on
// a non-finite value. Returns the number of cells with data.
std::uint64_t magnitudes(const store::Grid& grid, std::vector<float>& mag, std::vector<std::uint8_t>& valid) {
  const std::size_t bands = grid.bands();
  mag.assign(kMerlCells, 0.0f);
  valid.assign(kMerlCells, 0);
  parallel_for(kMerlCells, [&](std::size_t c) {
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
  }, kSlab);
  return std::uint64_t(std::count(valid.begin(), valid.end(), std::uint8_t(1)));
}

// s of the magnitude mapping: `given`, or when 0 a tenth of the median positive magnitude (1 if there is none).
double magnitude_scale(const std::vector<float>& mag, const std::vector<std::uint8_t>& valid, double given) {
  if (given != 0) return given;
  std::vector<float> positive;
  for (std::size_t c = 0; c < kMerlCells; ++c)
    if (valid[c] && mag[c] > 0) positive.push_back(mag[c]);
  if (positive.empty()) return 1;
  std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(positive.size() / 2), positive.end());
  return 0.1 * double(positive[positive.size() / 2]);
}

// The header's band count and k, checked (both formats).
std::pair<std::uint32_t, std::uint32_t> read_shape(Reader& r, const std::string& label) {
  const auto bands = r.get<std::uint32_t>("bands");
  const auto k = r.get<std::uint32_t>("k");
  if (bands < 1 || bands > kMaxBands) throw InputError(label + ": .spc header has " + std::to_string(bands) + " bands");
  if (k < 1 || k > bands)
    throw InputError(label + ": .spc header has k = " + std::to_string(k) + " for " + std::to_string(bands) + " bands");
  return {bands, k};
}

WavelengthGrid checked_wavelengths(std::vector<double> wl, const std::string& label) {
  try {
    return WavelengthGrid(std::move(wl));
  } catch (const Error& e) {
    throw InputError(label + ": .spc wavelengths are invalid: " + e.what());
  }
}

// The k x B basis stored as T (double in format 1, float in format 2), every value finite.
template <class T>
Eigen::MatrixXd read_basis(Reader& r, std::size_t k, std::size_t bands, const std::string& label) {
  std::vector<T> v(k * bands);
  std::memcpy(v.data(), r.take(sizeof(T) * v.size(), "basis"), sizeof(T) * v.size());
  Eigen::MatrixXd m(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(bands));
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t b = 0; b < bands; ++b) {
      if (!std::isfinite(v[j * bands + b])) throw InputError(label + ": .spc basis holds a non-finite value");
      m(Eigen::Index(j), Eigen::Index(b)) = double(v[j * bands + b]);
    }
  return m;
}

struct Parsed {
  Coding cd;
  WavelengthGrid wavelengths;
  std::string units, source, reference;
  std::uint64_t valid_cells = 0;
  std::size_t sections_at = 0;
};

// Magic, version and CRC of a .spc file of any version; returns the version.
std::uint32_t check_container(std::span<const std::uint8_t> bytes, const std::string& label) {
  if (bytes.size() < sizeof kSpcMagic + 4 || std::memcmp(bytes.data(), kSpcMagic, sizeof kSpcMagic) != 0)
    throw InputError(label + ": not a .spc file (it does not start with the SPECUSPC magic)");
  if (bytes.size() < 12 + 4) throw InputError(label + ": .spc file is truncated (" + std::to_string(bytes.size()) + " bytes)");
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

// The header of a format-1 file.
Parsed parse_header(std::span<const std::uint8_t> bytes, const std::string& label) {
  if (check_container(bytes, label) != 1)
    throw InputError(label + ": .spc format 2 has no format-1 header");
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic + 4, "magic and version");
  Parsed p;
  const auto [bands, k] = read_shape(r, label);
  p.cd.bands = bands;
  p.cd.k = k;
  p.cd.scale = r.get<double>("scale");
  p.cd.s = r.get<double>("magnitude scale");
  p.cd.step_m = r.get<double>("magnitude step");
  p.cd.step_c = r.get<double>("shape step");
  for (const auto& [v, what] : {std::pair{p.cd.scale, "scale"}, std::pair{p.cd.s, "magnitude scale"},
                                std::pair{p.cd.step_m, "magnitude step"}, std::pair{p.cd.step_c, "shape step"}})
    if (!(std::isfinite(v) && v > 0))
      throw InputError(label + ": .spc header field '" + what + "' is " + std::to_string(v) + "; it must be finite and positive");
  std::vector<double> wl(bands);
  std::memcpy(wl.data(), r.take(8 * bands, "wavelengths"), 8 * bands);
  p.wavelengths = checked_wavelengths(std::move(wl), label);
  p.cd.basis = read_basis<double>(r, k, bands, label);
  p.units = r.string("units");
  p.source = r.string("source");
  p.reference = r.string("basis reference");
  p.valid_cells = r.get<std::uint64_t>("valid cells");
  if (p.valid_cells > kMerlCells)
    throw InputError(label + ": .spc header claims " + std::to_string(p.valid_cells) + " valid cells of " +
                     std::to_string(kMerlCells));
  p.sections_at = r.at();
  return p;
}

}  // namespace

// ---- Format 2: the transform coder ----

namespace {

using wavelet::CubeLayout;
constexpr std::size_t kFold = std::size_t(kMerlPhiD) / 2;  // phi_d folded about pi/2: 90 sums, 90 differences
constexpr std::size_t kCube = std::size_t(kMerlThetaH) * kMerlThetaD * kFold;
constexpr double kRounding = 0.3;        // |w| / step + kRounding rounded down: a dead zone around 0
constexpr double kReconstruction = 0.1;  // a non-zero code q decodes to sign(q) (|q| + 0.1) step
constexpr std::int32_t kMaxCode = 1 << 28;
enum class Validity : std::uint8_t { all = 0, horizon = 1, coded = 2 };

// 1 for the cells whose centre has both directions above the horizon.
const std::vector<std::uint8_t>& horizon_mask() {
  static const std::vector<std::uint8_t> m = [] {
    std::vector<std::uint8_t> v(kMerlCells);
    for (std::size_t c = 0; c < kMerlCells; ++c) v[c] = brdf::merl_cell_valid(brdf::merl_cell(c));
    return v;
  }();
  return m;
}
constexpr std::array<std::size_t, 3> kGridDims{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD), std::size_t(kMerlPhiD)};

CubeLayout cube_layout(int levels) { return {{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD), kFold}, levels}; }

// The fields of a format-2 file that decoding needs besides the streams.
struct Transform {
  int levels = 4;
  double step_y = 0, step_c = 0, frequency = 1, reconstruction = kReconstruction;
  double specular = 1, extent = 1;  // steps times specular at theta_h index 0, rising linearly to 1 at `extent`
  double step(std::size_t channel) const { return channel == 0 ? step_y : step_c; }
};

// Calls f(index, step) for every coefficient of a cube of channel `channel`, the step of its subband: the
// channel's step, times frequency^(levels - 1 - l) for the detail bands of level l (0 finest), divided by the
// subband's synthesis norm so that a step is what an error costs in the channel's own values; and times the
// specular factor near the specular peak: specular + (1 - specular) min(1, h / extent), h the theta_h index its
// support is centred on ((offset in the subband + 1/2) 2^(l + 1), or 2^levels for the final low cube).
template <class F>
void for_each_coefficient(const CubeLayout& c, const Transform& t, std::size_t channel, F&& f) {
  const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
  auto band = [&](int l, int o, double step, double spread) {
    const auto r0 = c.range(l, o, 0), r1 = c.range(l, o, 1), r2 = c.range(l, o, 2);
    for (std::size_t i = r0[0]; i < r0[1]; ++i) {
      const double h = (double(i - r0[0]) + 0.5) * spread;
      const double at = step * (t.specular + (1 - t.specular) * std::min(1.0, h / t.extent));
      for (std::size_t j = r1[0]; j < r1[1]; ++j)
        for (std::size_t k = r2[0]; k < r2[1]; ++k) f(i * s0 + j * s1 + k, at);
    }
  };
  const double base = t.step(channel);
  band(c.levels, 0, base / c.synthesis_norm(c.levels, 0), std::ldexp(1.0, c.levels));
  for (int l = c.levels - 1; l >= 0; --l)
    for (int o = 1; o < 8; ++o)
      band(l, o, base * std::pow(t.frequency, c.levels - 1 - l) / c.synthesis_norm(l, o), std::ldexp(1.0, l + 1));
}

// Fills the cells of a 90 x 90 x 180 channel where `known` is 0 so that the channel stays smooth for the transform:
// along theta_d, then phi_d, then theta_h, each gap between known cells linearly and each end with its nearest
// known value; cells on lines with nothing known wait for the next axis (and are 0 if no cell is known).
void fill(std::vector<float>& v, std::vector<std::uint8_t> known) {
  const std::array<std::size_t, 3> n{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD), std::size_t(kMerlPhiD)};
  const std::array<std::size_t, 3> stride{kSlab, std::size_t(kMerlPhiD), 1};
  for (const std::size_t axis : {std::size_t(1), std::size_t(2), std::size_t(0)}) {
    const std::size_t a = (axis + 1) % 3, b = (axis + 2) % 3;
    for (std::size_t i = 0; i < n[a]; ++i)
      for (std::size_t j = 0; j < n[b]; ++j) {
        const std::size_t base = i * stride[a] + j * stride[b];
        std::ptrdiff_t last = -1;
        for (std::size_t t = 0; t <= n[axis]; ++t) {
          if (t < n[axis] && !known[base + t * stride[axis]]) continue;
          if (t == n[axis] && last < 0) break;  // nothing known on this line
          const float right = t < n[axis] ? v[base + t * stride[axis]] : v[base + std::size_t(last) * stride[axis]];
          const float left = last >= 0 ? v[base + std::size_t(last) * stride[axis]] : right;
          for (std::size_t u = std::size_t(last + 1); u < t; ++u) {
            const double w = last >= 0 && t < n[axis] ? double(u - std::size_t(last)) / double(t - std::size_t(last)) : 0.0;
            v[base + u * stride[axis]] = float(left + w * (right - left));
            known[base + u * stride[axis]] = 1;
          }
          last = std::ptrdiff_t(t);
        }
      }
  }
  for (std::size_t c = 0; c < v.size(); ++c)
    if (!known[c]) v[c] = 0;
}

// A filled channel folded about phi_d = pi/2 into its sum and difference cubes (isotropic reciprocal BRDFs are
// even there, so the difference is near zero): S = (v(p) + v(179 - p)) / 2, D = (v(p) - v(179 - p)) / 2.
void fold(const std::vector<float>& v, std::vector<float>& sum, std::vector<float>& diff) {
  sum.resize(kCube);
  diff.resize(kCube);
  for (std::size_t hd = 0; hd < std::size_t(kMerlThetaH) * kMerlThetaD; ++hd)
    for (std::size_t p = 0; p < kFold; ++p) {
      const float a = v[hd * kMerlPhiD + p], b = v[hd * kMerlPhiD + kMerlPhiD - 1 - p];
      sum[hd * kFold + p] = 0.5f * (a + b);
      diff[hd * kFold + p] = 0.5f * (a - b);
    }
}

// The magnitude and shape channels of a grid on a basis, transformed: 2 (k + 1) cubes (sum, difference per channel).
struct Model {
  std::size_t bands = 0, k = 0;
  double scale = 1, s = 1;
  std::vector<std::uint8_t> valid;
  std::uint64_t n_valid = 0;
  Validity validity = Validity::coded;
  std::vector<std::vector<float>> cubes;
};

Model transform_model(const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o) {
  Model md;
  md.bands = grid.bands();
  md.k = basis.k();
  md.scale = grid.scale;
  const std::size_t bands = md.bands, k = md.k;
  std::vector<float> mag;
  md.n_valid = magnitudes(grid, mag, md.valid);
  md.s = magnitude_scale(mag, md.valid, o.magnitude_scale);
  std::vector<std::vector<float>> ch(k + 1, std::vector<float>(kMerlCells, 0.0f));
  std::vector<std::uint8_t> shaped(kMerlCells, 0);
  const bool all = md.n_valid == kMerlCells, horizon = md.valid == horizon_mask();
  md.validity = all ? Validity::all : horizon ? Validity::horizon : Validity::coded;
  parallel_for(kMerlCells, [&](std::size_t c) {
    if (!md.valid[c]) return;
    const double m = mag[c];
    ch[0][c] = float(std::log1p(m / md.s));
    if (!(m > 0)) return;
    shaped[c] = 1;
    for (std::size_t j = 0; j < k; ++j) {
      double v = 0;
      for (std::size_t b = 0; b < bands; ++b) v += basis.rows(Eigen::Index(j), Eigen::Index(b)) * grid.brdf[b * kMerlCells + c];
      ch[j + 1][c] = float(v / m);
    }
  }, kSlab);
  md.cubes.resize(2 * (k + 1));
  const CubeLayout layout = cube_layout(o.levels);
  parallel_for(k + 1, [&](std::size_t j) {
    fill(ch[j], j == 0 ? md.valid : shaped);
    fold(ch[j], md.cubes[2 * j], md.cubes[2 * j + 1]);
    std::vector<float>().swap(ch[j]);
    wavelet::forward_cube(md.cubes[2 * j], layout);
    wavelet::forward_cube(md.cubes[2 * j + 1], layout);
  }, 1);
  return md;
}

std::vector<std::vector<std::int32_t>> quantise(const Model& md, const Transform& t) {
  std::vector<std::vector<std::int32_t>> q(md.cubes.size(), std::vector<std::int32_t>(kCube));
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(md.cubes.size(), [&](std::size_t cube) {
    const std::vector<float>& w = md.cubes[cube];
    std::int32_t* out = q[cube].data();
    for_each_coefficient(layout, t, cube / 2, [&](std::size_t i, double step) {
      const double a = std::floor(std::abs(double(w[i])) / step + kRounding);
      if (!(a < kMaxCode)) throw UsageError("encode: a transform coefficient needs a code beyond 2^28; raise the step");
      out[i] = std::int32_t(w[i] < 0 ? -a : a);
    });
  }, 1);
  return q;
}

// The coefficient form of quantised cubes: dequantised, inverse-transformed, unfolded, and per valid cell
// a_j = s expm1(max(0, y')) c'_j.
SpcCoefficients reconstruct(const std::vector<std::vector<std::int32_t>>& q, const Transform& t, std::size_t k,
                            double s, const std::vector<std::uint8_t>& valid, const std::string& label) {
  const CubeLayout layout = cube_layout(t.levels);
  std::vector<std::vector<float>> channel(k + 1, std::vector<float>(kMerlCells));
  parallel_for(k + 1, [&](std::size_t j) {
    std::array<std::vector<float>, 2> w{std::vector<float>(kCube), std::vector<float>(kCube)};
    for (std::size_t half = 0; half < 2; ++half) {
      const std::int32_t* in = q[2 * j + half].data();
      float* out = w[half].data();
      for_each_coefficient(layout, t, j, [&](std::size_t i, double step) {
        const std::int32_t v = in[i];
        out[i] = v == 0 ? 0.0f : float((v < 0 ? -1.0 : 1.0) * (std::abs(double(v)) + t.reconstruction) * step);
      });
      wavelet::inverse_cube(w[half], layout);
    }
    float* v = channel[j].data();
    for (std::size_t hd = 0; hd < std::size_t(kMerlThetaH) * kMerlThetaD; ++hd)
      for (std::size_t p = 0; p < kFold; ++p) {
        const float sum = w[0][hd * kFold + p], diff = w[1][hd * kFold + p];
        v[hd * kMerlPhiD + p] = sum + diff;
        v[hd * kMerlPhiD + kMerlPhiD - 1 - p] = sum - diff;
      }
  }, 1);
  SpcCoefficients out;
  out.values.assign(k * kMerlCells, 0.0f);
  parallel_for(kMerlCells, [&](std::size_t c) {
    if (!valid[c]) return;
    const double m = s * std::expm1(std::max(0.0, double(channel[0][c])));
    for (std::size_t j = 0; j < k; ++j) {
      const float a = float(m * double(channel[j + 1][c]));
      if (!std::isfinite(a))
        throw InputError(label + ": .spc coefficients decode beyond float range; the file was not written by specula encode");
      out.values[c * k + j] = a;
    }
  }, kSlab);
  out.valid = valid;
  return out;
}

std::vector<std::uint8_t> pack_v2(const Model& md, const SpcBasis& basis, const store::Grid& grid, const Transform& t,
                                  const std::vector<std::vector<std::int32_t>>& q, const std::string& source) {
  std::vector<std::vector<std::uint8_t>> streams(q.size());
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(q.size(), [&](std::size_t i) { streams[i] = encode_cube(q[i], layout); }, 1);
  std::size_t total = 1024 + 8 * md.bands * (md.k + 1) + grid.units.size() + source.size() + basis.reference.size();
  for (const auto& st : streams) total += 4 + st.size();
  std::vector<std::uint8_t> out;
  out.reserve(total);
  put_bytes(out, kSpcMagic, sizeof kSpcMagic);
  put(out, std::uint32_t(2));
  put(out, std::uint32_t(md.bands));
  put(out, std::uint32_t(md.k));
  put(out, md.scale);
  put(out, md.s);
  const auto& wl = grid.wavelengths;
  const bool uniform = wl.uniform() && wl.size() > 1;
  put(out, std::uint8_t(uniform ? 0 : 1));
  if (uniform) {
    put(out, wl.front());
    put(out, wl.step());
  } else {
    for (const double w : wl.values()) put(out, w);
  }
  for (std::size_t j = 0; j < md.k; ++j)
    for (std::size_t b = 0; b < md.bands; ++b) put(out, float(basis.rows(Eigen::Index(j), Eigen::Index(b))));
  put_string(out, grid.units);
  put_string(out, source);
  put_string(out, basis.reference);
  put(out, std::uint64_t(md.n_valid));
  put(out, std::uint8_t(md.validity));
  if (md.validity == Validity::coded) {
    const auto z = encode_mask(md.valid, horizon_mask(), kGridDims);
    put(out, std::uint32_t(z.size()));
    put_bytes(out, z.data(), z.size());
  }
  put(out, std::uint8_t(t.levels));
  put(out, t.step_y);
  put(out, t.step_c);
  put(out, t.frequency);
  put(out, t.reconstruction);
  put(out, t.specular);
  put(out, t.extent);
  for (const auto& s : streams) {
    put(out, std::uint32_t(s.size()));
    put_bytes(out, s.data(), s.size());
  }
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, out.data(), uInt(out.size()));
  put(out, std::uint32_t(crc));
  return out;
}

Transform transform_of(const SpcOptions& o, double step) {
  return {o.levels, step, step * o.shape_step_ratio, o.frequency_factor, kReconstruction, o.specular_factor, o.specular_extent};
}

// The finest step (of options o's ratios) whose codes all stay below kMaxCode / 2.
double finest_step(const Model& md, const SpcOptions& o) {
  const Transform unit = transform_of(o, 1);
  const CubeLayout layout = cube_layout(unit.levels);
  std::vector<double> need(md.cubes.size(), 0);
  parallel_for(md.cubes.size(), [&](std::size_t cube) {
    for_each_coefficient(layout, unit, cube / 2, [&](std::size_t i, double step) {
      need[cube] = std::max(need[cube], std::abs(double(md.cubes[cube][i])) / step);
    });
  }, 1);
  return *std::max_element(need.begin(), need.end()) / (kMaxCode / 2);
}

void check_transform_options(const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o) {
  if (grid.brdf.size() != grid.bands() * kMerlCells) throw UsageError("encode: grid values do not match bands x 90 x 90 x 180");
  if (!(std::isfinite(o.step) && o.step > 0 && o.step <= 10))
    throw UsageError("step = " + std::to_string(o.step) + ": give a number in (0, 10]");
  if (!(std::isfinite(o.shape_step_ratio) && o.shape_step_ratio > 0 && o.shape_step_ratio <= 1000))
    throw UsageError("shape_step_ratio = " + std::to_string(o.shape_step_ratio) + ": give a number in (0, 1000]");
  if (!(std::isfinite(o.frequency_factor) && o.frequency_factor >= 1 && o.frequency_factor <= 16))
    throw UsageError("frequency_factor = " + std::to_string(o.frequency_factor) + ": give a number in [1, 16]");
  if (o.levels < 1 || o.levels > 5) throw UsageError("levels = " + std::to_string(o.levels) + ": give 1 to 5");
  if (!(std::isfinite(o.specular_factor) && o.specular_factor > 0 && o.specular_factor <= 1))
    throw UsageError("specular_factor = " + std::to_string(o.specular_factor) + ": give a number in (0, 1]");
  if (!(std::isfinite(o.specular_extent) && o.specular_extent >= 1 && o.specular_extent <= 90))
    throw UsageError("specular_extent = " + std::to_string(o.specular_extent) + ": give 1 to 90 theta_h indices");
  if (!(std::isfinite(o.magnitude_scale) && o.magnitude_scale >= 0))
    throw UsageError("magnitude scale must be finite and >= 0 (0: automatic)");
  if (!(std::isfinite(grid.scale) && grid.scale > 0)) throw UsageError("encode: the grid's scale must be positive");
  if (basis.rows.cols() != Eigen::Index(grid.bands()) || !basis.wavelengths.approx_equal(grid.wavelengths))
    throw InputError("the grid has " + grid.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code a grid with a basis on its own wavelengths");
}

// Errors of a decoding against the grid, for SpcReport (values x scale, 1/sr), and the shape quantisation error.
void measure(const store::Grid& grid, const SpcCoefficients& c, const SpcBasis& basis, std::uint64_t bytes, SpcReport& r) {
  const std::size_t bands = grid.bands(), k = c.k();
  std::vector<double> sq(kMerlThetaH, 0), mx(kMerlThetaH, 0), resid(kMerlThetaH, 0), quant(kMerlThetaH, 0);
  parallel_for(std::size_t(kMerlThetaH), [&] { return std::vector<float>(bands); }, [&](std::size_t h, std::vector<float>& x) {
    Eigen::VectorXd r(static_cast<Eigen::Index>(bands)), a(static_cast<Eigen::Index>(k));
    for (std::size_t cell = h * kSlab; cell < (h + 1) * kSlab; ++cell) {
      if (!c.valid[cell]) continue;
      expand_cell(c.basis, c.values.data() + cell * k, x.data(), 1);
      double m = 0;
      for (std::size_t b = 0; b < bands; ++b) {
        const double e = (double(x[b]) - grid.brdf[b * kMerlCells + cell]) * grid.scale;
        sq[h] += e * e;
        mx[h] = std::max(mx[h], std::abs(e));
        r[Eigen::Index(b)] = grid.brdf[b * kMerlCells + cell];
        m += r[Eigen::Index(b)];
      }
      m /= double(bands);
      if (!(m > 0)) continue;
      r /= m;
      const Eigen::VectorXd coef = basis.rows * r;
      const Eigen::VectorXd rk = basis.rows.transpose() * coef;
      for (std::size_t j = 0; j < k; ++j) a[Eigen::Index(j)] = c.values[cell * k + j];
      const double ma = (c.basis.transpose() * a).mean();
      const Eigen::VectorXd rq = ma > 0 ? Eigen::VectorXd(c.basis.transpose() * a / ma) : Eigen::VectorXd(rk);
      resid[h] = std::max(resid[h], (r - rk).cwiseAbs().maxCoeff());
      quant[h] = std::max(quant[h], (rq - rk).cwiseAbs().maxCoeff());
    }
  });
  r = {};
  double total = 0;
  for (int h = 0; h < kMerlThetaH; ++h) {
    total += sq[std::size_t(h)];
    r.max_abs_error = std::max(r.max_abs_error, mx[std::size_t(h)]);
    r.max_shape_residual = std::max(r.max_shape_residual, resid[std::size_t(h)]);
    r.max_quantisation_error = std::max(r.max_quantisation_error, quant[std::size_t(h)]);
  }
  r.input_bytes = std::uint64_t(bands) * kMerlCells * 8;
  r.output_bytes = bytes;
  r.valid_cells = std::uint64_t(std::count(c.valid.begin(), c.valid.end(), std::uint8_t(1)));
  r.rms_error = r.valid_cells ? std::sqrt(total / double(r.valid_cells * bands)) : 0.0;
}

SpcCoefficients with_header(SpcCoefficients c, const store::Grid& grid, const SpcBasis& basis, const std::string& source) {
  c.wavelengths = grid.wavelengths;
  c.basis = basis.rows.cast<float>().cast<double>();  // as the file stores it
  c.scale = grid.scale;
  c.units = grid.units;
  c.source = source;
  c.reference = basis.reference;
  return c;
}

// The file of a transformed model at one step, and what it measures against the grid when asked.
std::vector<std::uint8_t> code_model(const Model& md, const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o,
                                     double step, SpcReport* report, const std::string& source) {
  const Transform t = transform_of(o, step);
  const auto q = quantise(md, t);
  auto bytes = pack_v2(md, basis, grid, t, q, source);
  if (report) {
    const SpcCoefficients c = with_header(reconstruct(q, t, md.k, md.s, md.valid, "encode"), grid, basis, source);
    measure(grid, c, basis, bytes.size(), *report);
    report->magnitude_scale = md.s * md.scale;
    report->magnitude_step = t.step_y;
    report->shape_step = t.step_c;
  }
  return bytes;
}

std::vector<std::uint8_t> encode_transform(const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o,
                                           SpcReport* report, const std::string& source) {
  check_transform_options(grid, basis, o);
  return code_model(transform_model(grid, basis, o), grid, basis, o, o.step, report, source);
}

SpcCoefficients decode_v2(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic + 4, "magic and version");
  const auto [bands, k] = read_shape(r, label);
  SpcCoefficients c;
  c.scale = r.get<double>("scale");
  const double s = r.get<double>("magnitude scale");
  for (const auto& [v, what] : {std::pair{c.scale, "scale"}, std::pair{s, "magnitude scale"}})
    if (!(std::isfinite(v) && v > 0))
      throw InputError(label + ": .spc header field '" + what + "' is " + std::to_string(v) + "; it must be finite and positive");
  const auto wl_kind = r.get<std::uint8_t>("wavelength kind");
  std::vector<double> wl(bands);
  if (wl_kind == 0) {
    const double first = r.get<double>("first wavelength"), step = r.get<double>("wavelength step");
    for (std::size_t b = 0; b < bands; ++b) wl[b] = first + double(b) * step;
  } else if (wl_kind == 1) {
    std::memcpy(wl.data(), r.take(8 * bands, "wavelengths"), 8 * bands);
  } else {
    throw InputError(label + ": .spc wavelength kind " + std::to_string(wl_kind) + " is neither 0 (uniform) nor 1 (list)");
  }
  c.wavelengths = checked_wavelengths(std::move(wl), label);
  c.basis = read_basis<float>(r, k, bands, label);
  c.units = r.string("units");
  c.source = r.string("source");
  c.reference = r.string("basis reference");
  if (header_only) return c;
  const auto n_valid = r.get<std::uint64_t>("valid cells");
  const auto kind = r.get<std::uint8_t>("validity kind");
  c.valid.assign(kMerlCells, 0);
  if (kind == std::uint8_t(Validity::all)) {
    std::fill(c.valid.begin(), c.valid.end(), 1);
  } else if (kind == std::uint8_t(Validity::horizon)) {
    c.valid = horizon_mask();
  } else if (kind == std::uint8_t(Validity::coded)) {
    const auto z = r.get<std::uint32_t>("validity");
    if (!decode_mask({r.take(z, "validity"), z}, horizon_mask(), kGridDims, c.valid))
      throw InputError(label + ": .spc validity stream ends before its cells; the file is corrupt");
  } else {
    throw InputError(label + ": .spc validity kind " + std::to_string(kind) + " is not 0 (all), 1 (horizon) or 2 (coded)");
  }
  const auto counted = std::uint64_t(std::count(c.valid.begin(), c.valid.end(), std::uint8_t(1)));
  if (counted != n_valid)
    throw InputError(label + ": .spc validity has " + std::to_string(counted) + " valid cells, the header says " +
                     std::to_string(n_valid));
  Transform t;
  t.levels = r.get<std::uint8_t>("levels");
  t.step_y = r.get<double>("magnitude step");
  t.step_c = r.get<double>("shape step");
  t.frequency = r.get<double>("frequency factor");
  t.reconstruction = r.get<double>("reconstruction offset");
  t.specular = r.get<double>("specular factor");
  t.extent = r.get<double>("specular extent");
  if (t.levels < 1 || t.levels > 5) throw InputError(label + ": .spc has " + std::to_string(t.levels) + " levels; 1 to 5 are valid");
  for (const auto& [v, what] : {std::pair{t.step_y, "magnitude step"}, std::pair{t.step_c, "shape step"},
                                std::pair{t.frequency, "frequency factor"}})
    if (!(std::isfinite(v) && v > 0 && v <= 1e6))
      throw InputError(label + ": .spc field '" + what + "' is " + std::to_string(v) + "; it must be in (0, 1e6]");
  if (!(std::isfinite(t.specular) && t.specular > 0 && t.specular <= 1))
    throw InputError(label + ": .spc specular factor " + std::to_string(t.specular) + " is outside (0, 1]");
  if (!(std::isfinite(t.extent) && t.extent >= 1 && t.extent <= 90))
    throw InputError(label + ": .spc specular extent " + std::to_string(t.extent) + " is outside [1, 90]");
  if (!(std::isfinite(t.reconstruction) && std::abs(t.reconstruction) < 1))
    throw InputError(label + ": .spc reconstruction offset " + std::to_string(t.reconstruction) + " is outside (-1, 1)");
  const std::size_t cubes = 2 * (std::size_t(k) + 1);
  std::vector<std::span<const std::uint8_t>> streams(cubes);
  for (std::size_t i = 0; i < cubes; ++i) {
    const auto n = r.get<std::uint32_t>("stream length");
    streams[i] = {r.take(n, "stream"), n};
  }
  if (r.at() != bytes.size() - 4)
    throw InputError(label + ": .spc file has " + std::to_string(bytes.size() - 4 - r.at()) + " unexpected bytes before its CRC");
  std::vector<std::vector<std::int32_t>> q(cubes, std::vector<std::int32_t>(kCube));
  std::vector<std::uint8_t> ok(cubes, 1);
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(cubes, [&](std::size_t i) { ok[i] = decode_cube(streams[i], layout, q[i]); }, 1);
  for (std::size_t i = 0; i < cubes; ++i)
    if (!ok[i]) throw InputError(label + ": .spc stream " + std::to_string(i) + " ends before its cube; the file is corrupt");
  SpcCoefficients v = reconstruct(q, t, k, s, c.valid, label);
  c.values = std::move(v.values);
  return c;
}

}  // namespace

std::vector<std::uint8_t> encode_spc_to_target(const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o,
                                               const SpcTarget& target, const Environment& env,
                                               SpcTargetReport& tr, SpcReport* report, const std::string& source) {
  check_transform_options(grid, basis, o);
  if (!(target.de00_mean > 0 && target.de00_p95 > 0 && std::isfinite(target.de00_mean) && std::isfinite(target.de00_p95)))
    throw UsageError("target: de00_mean and de00_p95 must be positive");
  if (target.max_trials < 2 || target.max_trials > 32) throw UsageError("target: max_trials must be 2 to 32");
  const Model md = transform_model(grid, basis, o);
  const SphereRenders reference = render_spheres({&grid}, env, target.size);
  if (!(reference.white.y() > 0))
    throw InputError("environment " + env.description + " sends no light to a surface facing the viewer; nothing maps to white");
  // A trial's excess: the larger of its mean and 95th percentile over their limits; it meets the target at <= 1.
  struct Trial {
    double step;
    De00 de;
    double excess;
  };
  auto trial = [&](double step) {
    const Transform t = transform_of(o, step);
    const auto q = quantise(md, t);
    const store::Grid g = expand_spc(with_header(reconstruct(q, t, md.k, md.s, md.valid, "encode"), grid, basis, source));
    const SphereRenders r = render_spheres({&g}, env, target.size);
    De00 de = de00_of_renders(reference.xyz[0], r.xyz[0], reference.covered, reference.white);
    const double excess = std::max(de.mean / target.de00_mean, de.p95 / target.de00_p95);
    ++tr.trials;
    return Trial{step, std::move(de), excess};
  };
  tr = {};
  std::optional<Trial> good, bad;
  if (!(std::isfinite(target.first_step) && target.first_step > 0 && target.first_step <= 10))
    throw UsageError("target: first_step must be in (0, 10]");
  // The rendered error grows about in proportion to the step, so each next step aims at an excess of 0.95: scaled
  // from a single trial (by 2 to 16 times), then by interpolating log excess against log step inside the bracket
  // (kept a tenth of the bracket away from its ends), until the bracket is within 20 %.
  constexpr double kAim = 0.95;
  const double finest = std::max(1e-6, finest_step(md, o));
  double step = std::max(target.first_step, finest);
  while (tr.trials < target.max_trials) {
    Trial t = trial(step);
    (t.excess <= 1 ? good : bad) = std::move(t);
    if (good && bad) {
      if (bad->step / good->step <= 1.2) break;
      const double xg = std::log(good->step), xb = std::log(bad->step);
      const double yg = std::log(std::max(good->excess, 1e-6)), yb = std::log(bad->excess);
      double x = yb > yg ? xg + (std::log(kAim) - yg) * (xb - xg) / (yb - yg) : 0.5 * (xg + xb);
      x = std::clamp(x, xg + 0.1 * (xb - xg), xb - 0.1 * (xb - xg));
      step = std::exp(x);
    } else if (good) {
      step = good->step * std::clamp(kAim / std::max(good->excess, 1e-6), 2.0, 16.0);
      if (step > 10) break;
    } else {
      if (bad->step <= finest) break;  // the target is out of reach: the basis or the float channels limit it
      step = std::max(finest, bad->step / std::clamp(bad->excess / kAim, 2.0, 16.0));
    }
  }
  const Trial& chosen = good ? *good : *bad;
  tr.reached = good.has_value();
  tr.step = chosen.step;
  tr.de00_mean = chosen.de.mean;
  tr.de00_p95 = chosen.de.p95;
  return code_model(md, grid, basis, o, chosen.step, report, source);
}

SpcBasis coding_basis(const store::Basis& basis, std::size_t k, const std::string& reference) {
  const bool pca = basis.method == "pca";
  const std::size_t have = basis.k() + (pca ? 1 : 0);
  if (k < 1 || k > std::min(have, basis.bands()))
    throw UsageError("k = " + std::to_string(k) + ": basis " + reference + " gives 1 to " +
                     std::to_string(std::min(have, basis.bands())) + " spectra" + (pca ? " (its mean and components)" : ""));
  Eigen::MatrixXd m(Eigen::Index(basis.bands()), Eigen::Index(k));
  std::size_t col = 0;
  if (pca) m.col(Eigen::Index(col++)) = basis.mean;
  for (Eigen::Index j = 0; col < k; ++j) m.col(Eigen::Index(col++)) = basis.components.row(j).transpose();
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(m);
  const Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(m.rows(), m.cols());
  const Eigen::VectorXd diag = qr.matrixQR().diagonal();
  if (diag.cwiseAbs().minCoeff() <= 1e-10 * diag.cwiseAbs().maxCoeff())
    throw InputError(reference + ": its first " + std::to_string(k) + " spectra are linearly dependent; use a smaller -k");
  return {basis.wavelengths, q.transpose(), reference};
}

namespace {
// Second moment of the grid's shapes r = x / mean(x) after removing their projection on `remove` (k x B, may
// be empty), over valid cells with a non-zero magnitude; the cell count in n.
Eigen::MatrixXd shape_moment(const store::Grid& grid, const Eigen::MatrixXd& remove, std::uint64_t& n) {
  const std::size_t b = grid.bands();
  if (grid.brdf.size() != b * kMerlCells) throw UsageError("basis fit: grid values do not match bands x 90 x 90 x 180");
  std::vector<Eigen::MatrixXd> part(kMerlThetaH, Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(b)));
  std::vector<std::uint64_t> count(kMerlThetaH, 0);
  parallel_for(std::size_t(kMerlThetaH), [&] { return Eigen::VectorXd(static_cast<Eigen::Index>(b)); },
               [&](std::size_t h, Eigen::VectorXd& r) {
    for (std::size_t c = h * kSlab; c < (h + 1) * kSlab; ++c) {
      double m = 0;
      bool valid = true;
      for (std::size_t j = 0; j < b; ++j) {
        const float v = grid.brdf[j * kMerlCells + c];
        valid &= v >= 0;
        r[Eigen::Index(j)] = v;
        m += v;
      }
      if (!valid || !(m > 0) || !std::isfinite(m)) continue;
      r *= double(b) / m;
      if (remove.rows() > 0) r -= remove.transpose() * (remove * r);
      part[h].selfadjointView<Eigen::Lower>().rankUpdate(r);
      ++count[h];
    }
  });
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(b));
  n = 0;
  for (int h = 0; h < kMerlThetaH; ++h) g += part[std::size_t(h)], n += count[std::size_t(h)];
  g.triangularView<Eigen::StrictlyUpper>() = g.transpose();
  return g;
}

// The top k eigenvectors of symmetric g as rows, each with its largest entry positive.
Eigen::MatrixXd top_rows(const Eigen::MatrixXd& g, std::size_t k) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(g);
  const Eigen::Index b = g.rows();
  Eigen::MatrixXd rows(static_cast<Eigen::Index>(k), b);
  for (std::size_t j = 0; j < k; ++j) {
    Eigen::VectorXd v = eig.eigenvectors().col(b - 1 - Eigen::Index(j));
    Eigen::Index at;
    v.cwiseAbs().maxCoeff(&at);
    if (v[at] < 0) v = -v;
    rows.row(Eigen::Index(j)) = v.transpose();
  }
  return rows;
}
}  // namespace

SpcBasis self_basis(const store::Grid& grid, std::size_t k) {
  const std::size_t b = grid.bands();
  if (k < 1 || k > b) throw UsageError("k = " + std::to_string(k) + ": give 1 to " + std::to_string(b) + " for a self basis");
  std::uint64_t n = 0;
  const Eigen::MatrixXd g = shape_moment(grid, Eigen::MatrixXd(0, Eigen::Index(b)), n);
  if (n == 0) throw InputError("the grid has no valid cell with a non-zero spectrum to fit a basis to");
  return {grid.wavelengths, top_rows(g, k), "self"};
}

SpcBasis augment_basis(const SpcBasis& basis, const store::Grid& grid, std::size_t extra) {
  const std::size_t b = grid.bands();
  if (basis.rows.cols() != Eigen::Index(b) || !basis.wavelengths.approx_equal(grid.wavelengths))
    throw InputError("the grid has " + grid.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code a grid with a basis on its own wavelengths");
  if (basis.k() + extra > b)
    throw UsageError("extra = " + std::to_string(extra) + ": with k = " + std::to_string(basis.k()) + " at most " +
                     std::to_string(b - basis.k()) + " more spectra fit in " + std::to_string(b) + " bands");
  if (extra == 0) return basis;
  std::uint64_t n = 0;
  const Eigen::MatrixXd g = shape_moment(grid, basis.rows, n);
  if (n == 0) throw InputError("the grid has no valid cell with a non-zero spectrum to fit a basis to");
  SpcBasis out = basis;
  out.rows.conservativeResize(Eigen::Index(basis.k() + extra), Eigen::NoChange);
  out.rows.bottomRows(Eigen::Index(extra)) = top_rows(g, extra);
  // Re-orthonormalise against rounding (the new rows are orthogonal to the old in exact arithmetic).
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(out.rows.transpose());
  Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(Eigen::Index(b), out.rows.rows());
  for (Eigen::Index j = 0; j < q.cols(); ++j)
    if (q.col(j).dot(out.rows.row(j).transpose()) < 0) q.col(j) = -q.col(j);
  out.rows = q.transpose();
  out.reference = basis.reference + "+" + std::to_string(extra);
  return out;
}

std::vector<std::uint8_t> encode_spc(const store::Grid& grid, const SpcBasis& basis, const SpcOptions& o,
                                     SpcReport* report, const std::string& source) {
  if (o.method == SpcMethod::transform) return encode_transform(grid, basis, o, report, source);
  const std::size_t bands = grid.bands(), k = basis.k();
  if (grid.brdf.size() != bands * kMerlCells) throw UsageError("encode: grid values do not match bands x 90 x 90 x 180");
  if (!(std::isfinite(o.max_error) && o.max_error > 0 && o.max_error <= 1))
    throw UsageError("max_error = " + std::to_string(o.max_error) + ": give a number in (0, 1]");
  if (!(std::isfinite(o.magnitude_scale) && o.magnitude_scale >= 0))
    throw UsageError("magnitude scale must be finite and >= 0 (0: automatic)");
  if (o.zstd_level < 1 || o.zstd_level > 19) throw UsageError("zstd level must be 1 to 19");
  if (!(std::isfinite(grid.scale) && grid.scale > 0)) throw UsageError("encode: the grid's scale must be positive");
  if (basis.rows.cols() != Eigen::Index(bands) || !basis.wavelengths.approx_equal(grid.wavelengths))
    throw InputError("the grid has " + grid.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code a grid with a basis on its own wavelengths");
  if (k < 1 || k > bands) throw UsageError("encode: the basis must hold 1 to bands spectra");

  std::vector<float> mag;
  std::vector<std::uint8_t> valid;
  const std::uint64_t n_valid = magnitudes(grid, mag, valid);
  Coding cd;
  cd.bands = bands;
  cd.k = k;
  cd.scale = grid.scale;
  cd.basis = basis.rows;
  cd.s = magnitude_scale(mag, valid, o.magnitude_scale);
  cd.step_m = 2 * std::log1p(o.max_error);
  const double spread = basis.rows.cwiseAbs().colwise().sum().maxCoeff();
  cd.step_c = 2 * o.max_error / spread;

  // Codes (channel 0: magnitude, 1..k: shape) and their residuals, slab by slab.
  const std::size_t channels = k + 1;
  std::vector<std::vector<std::vector<std::int32_t>>> residuals(kMerlThetaH, std::vector<std::vector<std::int32_t>>(channels));
  std::vector<double> slab_sq(kMerlThetaH, 0), slab_max(kMerlThetaH, 0), slab_resid(kMerlThetaH, 0), slab_quant(kMerlThetaH, 0);
  struct SlabScratch {
    std::vector<std::int32_t> q;
    Eigen::VectorXd r, c;
    std::vector<float> a;
    std::vector<float> out;
  };
  auto scratch = [&] {
    return SlabScratch{std::vector<std::int32_t>(channels * kSlab), Eigen::VectorXd(static_cast<Eigen::Index>(bands)),
                       Eigen::VectorXd(static_cast<Eigen::Index>(k)), std::vector<float>(k), std::vector<float>(bands)};
  };
  parallel_for(std::size_t(kMerlThetaH), scratch, [&](std::size_t slab, SlabScratch& t) {
    const int h = int(slab);
    auto& q = t.q;
    auto& r = t.r;
    auto& c = t.c;
    auto& a = t.a;
    auto& out = t.out;
    const std::size_t base = std::size_t(h) * kSlab;
    const std::uint8_t* vs = valid.data() + base;
    double sq = 0, mx = 0, resid = 0, quant = 0;
    for (std::size_t i = 0; i < kSlab; ++i) {
      if (!vs[i]) continue;
      const std::size_t cell = base + i;
      const double m = mag[cell];
      q[i] = to_code(std::log1p(m / cd.s) / cd.step_m, "the magnitude");
      for (std::size_t b = 0; b < bands; ++b) r[Eigen::Index(b)] = m > 0 ? grid.brdf[b * kMerlCells + cell] / m : 0.0;
      c.noalias() = basis.rows * r;
      for (std::size_t j = 0; j < k; ++j) q[(j + 1) * kSlab + i] = to_code(c[Eigen::Index(j)] / cd.step_c, "a shape coefficient");
      // What the decoder will produce, for the report.
      coefficients(cd, q[i], q.data() + kSlab + i, kSlab, a.data());
      expand_cell(cd.basis, a.data(), out.data(), 1);
      const Eigen::VectorXd rk = basis.rows.transpose() * c;
      for (std::size_t b = 0; b < bands; ++b) {
        const double e = (double(out[b]) - grid.brdf[b * kMerlCells + cell]) * cd.scale;
        sq += e * e;
        mx = std::max(mx, std::abs(e));
        if (m > 0) {
          resid = std::max(resid, std::abs(r[Eigen::Index(b)] - rk[Eigen::Index(b)]));
          double shape_b = 0;  // r'_b = (V^T c')_b
          for (std::size_t j = 0; j < k; ++j) shape_b += double(q[(j + 1) * kSlab + i]) * cd.step_c * basis.rows(Eigen::Index(j), Eigen::Index(b));
          quant = std::max(quant, std::abs(shape_b - rk[Eigen::Index(b)]));
        }
      }
    }
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const std::int32_t* qc = q.data() + ch * kSlab;
      auto& res = residuals[std::size_t(h)][ch];
      for (std::size_t d = 0; d < std::size_t(kMerlThetaD); ++d)
        for (std::size_t p = 0; p < std::size_t(kMerlPhiD); ++p) {
          const std::size_t i = d * kMerlPhiD + p;
          if (!vs[i]) continue;
          const std::int64_t e = std::int64_t(qc[i]) - predict(qc, vs, d, p);
          if (e < std::numeric_limits<std::int32_t>::min() || e > std::numeric_limits<std::int32_t>::max())
            throw UsageError("encode: a prediction residual exceeds 32 bits; raise max_error");
          res.push_back(std::int32_t(e));
        }
    }
    slab_sq[std::size_t(h)] = sq, slab_max[std::size_t(h)] = mx, slab_resid[std::size_t(h)] = resid,
    slab_quant[std::size_t(h)] = quant;
  });

  std::vector<std::uint8_t> out;
  put_bytes(out, kSpcMagic, sizeof kSpcMagic);
  put(out, std::uint32_t(1));
  put(out, std::uint32_t(bands));
  put(out, std::uint32_t(k));
  put(out, cd.scale);
  put(out, cd.s);
  put(out, cd.step_m);
  put(out, cd.step_c);
  for (const double w : grid.wavelengths.values()) put(out, w);
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t b = 0; b < bands; ++b) put(out, basis.rows(Eigen::Index(j), Eigen::Index(b)));
  put_string(out, grid.units);
  put_string(out, source);
  put_string(out, basis.reference);
  put(out, std::uint64_t(n_valid));
  // Sections: the validity bitmap, then each channel's residuals; each as raw length, width, zstd length, frame.
  std::vector<std::uint8_t> bitmap((kMerlCells + 7) / 8, 0);
  for (std::size_t c = 0; c < kMerlCells; ++c)
    if (valid[c]) bitmap[c / 8] |= std::uint8_t(1u << (c % 8));
  auto section = [&](const std::vector<std::uint8_t>& raw, std::uint8_t width) {
    const auto z = zstd_compress(raw, o.zstd_level);
    put(out, std::uint64_t(raw.size()));
    put(out, width);
    put(out, std::uint64_t(z.size()));
    put_bytes(out, z.data(), z.size());
  };
  section(bitmap, 1);
  for (std::size_t ch = 0; ch < channels; ++ch) {
    std::vector<std::int32_t> all;
    all.reserve(n_valid);
    for (int h = 0; h < kMerlThetaH; ++h) {
      const auto& v = residuals[std::size_t(h)][ch];
      all.insert(all.end(), v.begin(), v.end());
    }
    std::uint8_t width = 1;
    const auto raw = planes(all, width);
    section(raw, width);
  }
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, out.data(), uInt(out.size()));
  put(out, std::uint32_t(crc));

  if (report) {
    double sq = 0;
    *report = {};
    for (int h = 0; h < kMerlThetaH; ++h) {
      sq += slab_sq[std::size_t(h)];
      report->max_abs_error = std::max(report->max_abs_error, slab_max[std::size_t(h)]);
      report->max_shape_residual = std::max(report->max_shape_residual, slab_resid[std::size_t(h)]);
      report->max_quantisation_error = std::max(report->max_quantisation_error, slab_quant[std::size_t(h)]);
    }
    report->input_bytes = std::uint64_t(bands) * kMerlCells * 8;
    report->output_bytes = out.size();
    report->valid_cells = n_valid;
    report->magnitude_scale = cd.s * cd.scale;
    report->magnitude_step = cd.step_m;
    report->shape_step = cd.step_c;
    report->rms_error = n_valid ? std::sqrt(sq / double(n_valid * bands)) : 0.0;
  }
  return out;
}

SpcBasis spc_basis(std::span<const std::uint8_t> bytes, const std::string& label) {
  if (check_container(bytes, label) == 2) {
    const SpcCoefficients c = decode_v2(bytes, label, true);
    return {c.wavelengths, c.basis, c.reference};
  }
  const Parsed p = parse_header(bytes, label);
  return {p.wavelengths, p.cd.basis, p.reference};
}

SpcCoefficients decode_spc_coefficients(std::span<const std::uint8_t> bytes, const std::string& label) {
  if (check_container(bytes, label) == 2) return decode_v2(bytes, label, false);
  const Parsed p = parse_header(bytes, label);
  const Coding& cd = p.cd;
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(p.sections_at, "header");
  auto section = [&](std::size_t expect_raw, bool residuals, const char* what, std::uint8_t& width) {
    const auto raw = r.get<std::uint64_t>(what);
    width = r.get<std::uint8_t>(what);
    const auto z = r.get<std::uint64_t>(what);
    if (residuals ? !(width == 1 || width == 2 || width == 4) : width != 1)
      throw InputError(label + ": .spc section " + what + " has value width " + std::to_string(width));
    if (raw != expect_raw * width)
      throw InputError(label + ": .spc section " + what + " holds " + std::to_string(raw) + " bytes, expected " +
                       std::to_string(expect_raw * width));
    const std::uint8_t* src = r.take(z, what);
    std::vector<std::uint8_t> out(raw);
    zstd_decompress(src, z, out, label, what);
    return out;
  };
  std::uint8_t width = 1;
  const auto bitmap = section((kMerlCells + 7) / 8, false, "validity", width);
  std::vector<std::uint8_t> valid(kMerlCells);
  std::uint64_t n_valid = 0;
  for (std::size_t c = 0; c < kMerlCells; ++c) n_valid += valid[c] = (bitmap[c / 8] >> (c % 8)) & 1u;
  if (n_valid != p.valid_cells)
    throw InputError(label + ": .spc validity map has " + std::to_string(n_valid) + " valid cells, the header says " +
                     std::to_string(p.valid_cells));
  const std::size_t channels = cd.k + 1;
  std::vector<std::vector<std::uint8_t>> res(channels);
  std::vector<std::uint8_t> widths(channels);
  for (std::size_t ch = 0; ch < channels; ++ch) {
    const std::string what = ch == 0 ? "magnitude" : "shape " + std::to_string(ch);
    res[ch] = section(n_valid, true, what.c_str(), widths[ch]);
  }
  if (r.at() != bytes.size() - 4)
    throw InputError(label + ": .spc file has " + std::to_string(bytes.size() - 4 - r.at()) +
                     " unexpected bytes before its CRC");
  std::vector<std::uint64_t> first(kMerlThetaH + 1, 0);  // valid cells before each slab
  for (int h = 0; h < kMerlThetaH; ++h) {
    std::uint64_t n = 0;
    for (std::size_t i = 0; i < kSlab; ++i) n += valid[std::size_t(h) * kSlab + i];
    first[std::size_t(h) + 1] = first[std::size_t(h)] + n;
  }
  SpcCoefficients g;
  g.wavelengths = p.wavelengths;
  g.basis = cd.basis;
  g.scale = cd.scale;
  g.units = p.units;
  g.source = p.source;
  g.reference = p.reference;
  g.values.assign(cd.k * kMerlCells, 0.0f);
  struct SlabScratch {
    std::vector<std::int32_t> q;
  };
  auto scratch = [&] { return SlabScratch{std::vector<std::int32_t>(channels * kSlab, 0)}; };
  parallel_for(std::size_t(kMerlThetaH), scratch, [&](std::size_t slab, SlabScratch& t) {
    const int h = int(slab);
    auto& q = t.q;
    const std::size_t base = std::size_t(h) * kSlab;
    const std::uint8_t* vs = valid.data() + base;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      std::int32_t* qc = q.data() + ch * kSlab;
      std::uint64_t at = first[std::size_t(h)];
      for (std::size_t d = 0; d < std::size_t(kMerlThetaD); ++d)
        for (std::size_t pd = 0; pd < std::size_t(kMerlPhiD); ++pd) {
          const std::size_t i = d * kMerlPhiD + pd;
          if (!vs[i]) continue;
          // Wraps like the encoder's int32 arithmetic; a corrupt residual gives a wrong value, never a crash.
          qc[i] = std::int32_t(std::uint32_t(predict(qc, vs, d, pd)) +
                               std::uint32_t(unplane(res[ch].data(), n_valid, widths[ch], at++)));
        }
    }
    for (std::size_t i = 0; i < kSlab; ++i) {
      if (!vs[i]) continue;
      float* a = g.values.data() + (base + i) * cd.k;
      coefficients(cd, q[i], q.data() + kSlab + i, kSlab, a);
      for (std::size_t j = 0; j < cd.k; ++j)
        if (!std::isfinite(a[j]))
          throw InputError(label + ": .spc codes decode to values beyond float range; the file was not written by "
                                   "specula encode");
    }
  });
  g.valid = std::move(valid);
  return g;
}

store::Grid expand_spc(const SpcCoefficients& c) {
  const std::size_t k = c.k(), bands = c.bands();
  if (c.values.size() != k * kMerlCells || c.valid.size() != kMerlCells)
    throw UsageError("expand_spc: coefficients do not match k x 90 x 90 x 180 cells");
  store::Grid g;
  g.wavelengths = c.wavelengths;
  g.scale = c.scale;
  g.units = c.units;
  g.provenance.source_file = c.source;
  g.provenance.importer = "decode " + c.reference;
  g.brdf.assign(bands * kMerlCells, -1.0f);
  parallel_for(kMerlCells, [&](std::size_t cell) {
    if (c.valid[cell]) expand_cell(c.basis, c.values.data() + cell * k, g.brdf.data() + cell, kMerlCells);
  }, kSlab);
  return g;
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
