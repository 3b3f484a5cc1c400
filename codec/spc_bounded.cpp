// .spc format 1, the bounded method: magnitude and shape codes kept within a stated error, predicted from their
// neighbours along phi_d and theta_d, the residuals split into byte planes and coded with zstd.
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "specula/codec/spc_detail.h"
#include "specula/core/parallel.h"

namespace specula::codec::detail {

std::vector<std::uint8_t> zstd_compress(const std::vector<std::uint8_t>& raw, int level) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(raw.size()));
  const std::size_t n = ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), level);
  if (ZSTD_isError(n)) throw LibraryError(std::string("zstd: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

void zstd_decompress(const std::uint8_t* src, std::size_t size, std::vector<std::uint8_t>& out,
                     const std::string& label, const char* what) {
  const unsigned long long content = ZSTD_getFrameContentSize(src, size);
  if (content != out.size())
    throw InputError(label + ": .spc section " + what + " is corrupt: its zstd frame holds " +
                     (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN
                          ? std::string("an unknown size")
                          : std::to_string(content)) +
                     " bytes, the header says " + std::to_string(out.size()));
  const std::size_t n = ZSTD_decompress(out.data(), out.size(), src, size);
  if (ZSTD_isError(n) || n != out.size())
    throw InputError(label + ": .spc section " + what +
                     " is corrupt: " + (ZSTD_isError(n) ? std::string(ZSTD_getErrorName(n)) : "short frame"));
}

namespace {

// Predicted code of cell (d, p) of one theta_h slab from its already-coded neighbours along phi_d and
// theta_d: the plane through three of them when all are valid, else the nearest valid one, else 0.
inline std::int64_t predict(const std::int32_t* q, const std::uint8_t* valid, std::size_t d, std::size_t p) {
  const std::size_t i = d * kMerlPhiD + p;
  const bool a = p > 0 && valid[i - 1], b = d > 0 && valid[i - kMerlPhiD],
             c = p > 0 && d > 0 && valid[i - kMerlPhiD - 1];
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
  if (!(std::abs(r) < 2e9))
    throw UsageError("encode: " + what + " needs a code of " + std::to_string(r) + ", beyond 32 bits; raise max_error");
  return std::int32_t(r);
}

struct Parsed {
  Coding cd;
  WavelengthGrid wavelengths;
  std::string units, source, reference;
  std::uint64_t valid_cells = 0;
  std::size_t sections_at = 0;
};

// The header of a format-1 file.
Parsed parse_header(std::span<const std::uint8_t> bytes, const std::string& label) {
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
      throw InputError(label + ": .spc header field '" + what + "' is " + std::to_string(v) +
                       "; it must be finite and positive");
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

// Per slab of theta_h: each channel's prediction residuals and the slab's error statistics.
struct CodedSlabs {
  std::vector<std::vector<std::vector<std::int32_t>>> residuals;  // [slab][channel]
  std::vector<double> sq, max, resid, quant;
};

void check_bounded(const store::Grid& grid, const SpcBasis& basis, const SpcBoundedOptions& o) {
  const std::size_t bands = grid.bands(), k = basis.k();
  if (grid.brdf.size() != bands * kMerlCells)
    throw UsageError("encode: grid values do not match bands x 90 x 90 x 180");
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
}

// Codes (channel 0: magnitude, 1..k: shape) and their residuals, slab by slab.
CodedSlabs code_slabs(const store::Grid& grid, const SpcBasis& basis, const Coding& cd, const std::vector<float>& mag,
                      const std::vector<std::uint8_t>& valid) {
  const std::size_t bands = grid.bands(), k = basis.k(), channels = k + 1;
  CodedSlabs slabs;
  auto& residuals = slabs.residuals;
  residuals.assign(kMerlThetaH, std::vector<std::vector<std::int32_t>>(channels));
  auto &slab_sq = slabs.sq, &slab_max = slabs.max, &slab_resid = slabs.resid, &slab_quant = slabs.quant;
  for (auto* v : {&slab_sq, &slab_max, &slab_resid, &slab_quant}) v->assign(kMerlThetaH, 0);
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
      for (std::size_t j = 0; j < k; ++j)
        q[(j + 1) * kSlab + i] = to_code(c[Eigen::Index(j)] / cd.step_c, "a shape coefficient");
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
          for (std::size_t j = 0; j < k; ++j)
            shape_b += double(q[(j + 1) * kSlab + i]) * cd.step_c * basis.rows(Eigen::Index(j), Eigen::Index(b));
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
  return slabs;
}

// The format-1 container: header, validity bitmap and each channel's residuals, zstd-compressed, and the CRC.
std::vector<std::uint8_t> write_bounded(const store::Grid& grid, const SpcBasis& basis, const Coding& cd,
                                        const CodedSlabs& slabs, const std::vector<std::uint8_t>& valid,
                                        std::uint64_t n_valid, const SpcBoundedOptions& o, const std::string& source) {
  const std::size_t bands = grid.bands(), k = basis.k(), channels = k + 1;
  const auto& residuals = slabs.residuals;
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
  put(out, crc32_of(out));
  return out;
}

void report_bounded(const CodedSlabs& slabs, const Coding& cd, std::size_t bands, std::uint64_t n_valid,
                    std::size_t out_bytes, SpcReport* report) {
  const auto &slab_sq = slabs.sq, &slab_max = slabs.max, &slab_resid = slabs.resid, &slab_quant = slabs.quant;
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
    report->output_bytes = out_bytes;
    report->valid_cells = n_valid;
    report->magnitude_scale = cd.s * cd.scale;
    report->magnitude_step = cd.step_m;
    report->shape_step = cd.step_c;
    report->rms_error = n_valid ? std::sqrt(sq / double(n_valid * bands)) : 0.0;
  }
}

}  // namespace

std::vector<std::uint8_t> encode_bounded(const store::Grid& grid, const SpcBasis& basis, const SpcBoundedOptions& o,
                                         SpcReport* report, const std::string& source) {
  check_bounded(grid, basis, o);
  const std::size_t bands = grid.bands(), k = basis.k();
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

  const CodedSlabs slabs = code_slabs(grid, basis, cd, mag, valid);
  std::vector<std::uint8_t> out = write_bounded(grid, basis, cd, slabs, valid, n_valid, o, source);
  report_bounded(slabs, cd, bands, n_valid, out.size(), report);
  return out;
}

SpcCoefficients decode_bounded(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  const Parsed p = parse_header(bytes, label);
  if (header_only) {
    SpcCoefficients h;
    h.wavelengths = p.wavelengths;
    h.basis = p.cd.basis;
    h.scale = p.cd.scale;
    h.units = p.units;
    h.source = p.source;
    h.reference = p.reference;
    return h;
  }
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
          throw InputError(label +
                           ": .spc codes decode to values beyond float range; the file was not written by "
                           "specula encode");
    }
  });
  g.valid = std::move(valid);
  return g;
}

}  // namespace specula::codec::detail
