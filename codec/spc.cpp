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
  const auto* b = static_cast<const std::uint8_t*>(p);
  out.insert(out.end(), b, b + n);
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

struct Parsed {
  Coding cd;
  WavelengthGrid wavelengths;
  std::string units, source, reference;
  std::uint64_t valid_cells = 0;
  std::size_t sections_at = 0;
};

Parsed parse_header(std::span<const std::uint8_t> bytes, const std::string& label) {
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
  Parsed p;
  const auto bands = r.get<std::uint32_t>("bands");
  const auto k = r.get<std::uint32_t>("k");
  if (bands < 1 || bands > kMaxBands) throw InputError(label + ": .spc header has " + std::to_string(bands) + " bands");
  if (k < 1 || k > bands)
    throw InputError(label + ": .spc header has k = " + std::to_string(k) + " for " + std::to_string(bands) + " bands");
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
  try {
    p.wavelengths = WavelengthGrid(wl);
  } catch (const Error& e) {
    throw InputError(label + ": .spc wavelengths are invalid: " + e.what());
  }
  p.cd.basis.resize(k, bands);
  std::vector<double> basis(std::size_t(k) * bands);
  std::memcpy(basis.data(), r.take(8 * basis.size(), "basis"), 8 * basis.size());
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t b = 0; b < bands; ++b) {
      const double v = basis[j * bands + b];
      if (!std::isfinite(v)) throw InputError(label + ": .spc basis holds a non-finite value");
      p.cd.basis(Eigen::Index(j), Eigen::Index(b)) = v;
    }
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

  // Magnitudes and validity.
  std::vector<float> mag(kMerlCells, -1.0f);
  std::vector<std::uint8_t> valid(kMerlCells, 0);
  parallel_for(kMerlCells, [&](std::size_t c) {
    double m = 0;
    bool ok = true;
    for (std::size_t b = 0; b < bands; ++b) {
      const float v = grid.brdf[b * kMerlCells + c];
      if (!std::isfinite(v)) throw InputError("the grid holds a non-finite value; it cannot be coded");
      ok &= v >= 0;
      m += v;
    }
    if (ok) {
      valid[c] = 1;
      mag[c] = float(m / double(bands));
    }
  }, kSlab);
  Coding cd;
  cd.bands = bands;
  cd.k = k;
  cd.scale = grid.scale;
  cd.basis = basis.rows;
  cd.s = o.magnitude_scale;
  std::uint64_t n_valid = 0;
  for (const auto v : valid) n_valid += v;
  if (cd.s == 0) {
    std::vector<float> positive;
    for (std::size_t c = 0; c < kMerlCells; ++c)
      if (valid[c] && mag[c] > 0) positive.push_back(mag[c]);
    if (positive.empty()) {
      cd.s = 1;
    } else {
      std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(positive.size() / 2), positive.end());
      cd.s = 0.1 * double(positive[positive.size() / 2]);
    }
  }
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
  put(out, kSpcVersion);
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
  const Parsed p = parse_header(bytes, label);
  return {p.wavelengths, p.cd.basis, p.reference};
}

SpcCoefficients decode_spc_coefficients(std::span<const std::uint8_t> bytes, const std::string& label) {
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
