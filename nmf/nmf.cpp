#include "specula/nmf/nmf.h"

#include <immintrin.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numeric>
#include <random>
#include <sstream>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/nnls.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/nmf/checkpoint.h"

namespace specula::nmf {
namespace {

using store::BlockReader;
constexpr std::size_t kTile = 256;

// Blocks per range of a pass that needs no basis updates (memory per thread grows with it).
constexpr std::size_t kRangeBlocks = 32;
// At most this many epochs on the warm-up sample.
constexpr std::size_t kWarmupEpochs = 100;

// Sums stats over the ranks in rank order: every field is packed into one vector of doubles (counters are
// exact in a double up to 2^53).
template <class Stats>
void sum_over_ranks(const Collective& ranks, Stats& s) {
  if (ranks.size() == 1) return;
  std::vector<double> packed;
  s.fields([&](double* p, std::size_t n) { packed.insert(packed.end(), p, p + n); },
           [&](std::uint64_t& c) { packed.push_back(double(c)); });
  sum_in_rank_order(ranks, packed);
  std::size_t at = 0;
  s.fields([&](double* p, std::size_t n) { std::copy_n(packed.data() + at, n, p), at += n; },
           [&](std::uint64_t& c) { c = std::uint64_t(packed[at++]); });
}

// Runs fn(block_index, raw, stats) over blocks [first, last) on all threads and returns the per-block
// statistics summed in block order: the same for any thread count. Under several ranks each runs a
// contiguous share of the blocks and the shares' sums are added in rank order.
template <class Stats, class Fn>
Stats reduce_range(const Collective& ranks, const BlockReader& reader, const Stats& zero, std::size_t first,
                   std::size_t last, Progress& progress, Fn&& fn, std::size_t stride = 1) {
  const Share share = share_of(ranks, (last - first + stride - 1) / stride);
  first += share.first * stride;
  const std::size_t n = share.last - share.first;
  std::vector<Stats> part(n, zero);
  parallel_for(
      n, [] { return BlockReader::RawBlock(); },
      [&](std::size_t j, BlockReader::RawBlock& raw) {
        const std::size_t block = first + j * stride;
        reader.read_raw(block, raw);
        fn(block, raw, part[j]);
        progress.advance(raw.valid);
      });
  Stats total = zero;
  for (const auto& p : part) total += p;
  sum_over_ranks(ranks, total);
  return total;
}

// The same over every block: each rank takes a contiguous share of all blocks and reduces it in ranges of
// kRangeBlocks (so memory does not grow with the number of blocks); the shares are then added in rank order.
template <class Stats, class Fn>
Stats reduce_all(const Collective& ranks, const BlockReader& reader, const Stats& zero, Progress& progress, Fn&& fn) {
  Stats total = zero;
  const Share share = share_of(ranks, reader.block_count());
  for (std::size_t first = share.first; first < share.last; first += kRangeBlocks)
    total +=
        reduce_range(single_process(), reader, zero, first, std::min(share.last, first + kRangeBlocks), progress, fn);
  sum_over_ranks(ranks, total);
  return total;
}

template <class Stats, class Fn>
Stats reduce_blocks(const Collective& ranks, const BlockReader& reader, const Stats& zero, const std::string& label,
                    Fn&& fn) {
  Progress progress(label, reader.spectra());
  return reduce_all(ranks, reader, zero, progress, fn);
}

// Copies one spectrum of b floats into t as doubles with negatives set to zero; counts non-finite and negative
// values and adds the sum of squares of the copied values to sq.
inline void clip_spectrum(const float* x, std::size_t b, double* t, unsigned& bad, unsigned& neg, double& sq) {
  std::size_t k = 0;
#if defined(__AVX2__)
  const __m256 zero = _mm256_setzero_ps();
  __m256i nbad = _mm256_setzero_si256(), nneg = nbad;
  __m256d acc = _mm256_setzero_pd();
  for (; k + 8 <= b; k += 8) {
    const __m256 v = _mm256_loadu_ps(x + k);
    const __m256 finite = _mm256_cmp_ps(_mm256_sub_ps(v, v), zero, _CMP_EQ_OQ);  // false for NaN and +-Inf
    const __m256 negative = _mm256_cmp_ps(v, zero, _CMP_LT_OQ);
    nbad =
        _mm256_sub_epi32(nbad, _mm256_castps_si256(_mm256_xor_ps(finite, _mm256_castsi256_ps(_mm256_set1_epi32(-1)))));
    nneg = _mm256_sub_epi32(nneg, _mm256_castps_si256(negative));
    const __m256 c = _mm256_max_ps(v, zero);
    const __m256d lo = _mm256_cvtps_pd(_mm256_castps256_ps128(c)), hi = _mm256_cvtps_pd(_mm256_extractf128_ps(c, 1));
    _mm256_storeu_pd(t + k, lo);
    _mm256_storeu_pd(t + k + 4, hi);
    acc = _mm256_fmadd_pd(lo, lo, _mm256_fmadd_pd(hi, hi, acc));
  }
  alignas(32) std::uint32_t cb[8], cn[8];
  alignas(32) double ca[4];
  _mm256_store_si256(reinterpret_cast<__m256i*>(cb), nbad);
  _mm256_store_si256(reinterpret_cast<__m256i*>(cn), nneg);
  _mm256_store_pd(ca, acc);
  for (int q = 0; q < 8; ++q) {
    bad += cb[q];
    neg += cn[q];
  }
  sq += (ca[0] + ca[1]) + (ca[2] + ca[3]);
#endif
  for (; k < b; ++k) {
    const float v = x[k];
    bad += (v - v) != 0.0f;
    neg += v < 0.0f;
    const double d = v < 0.0f ? 0.0 : double(v);
    t[k] = d;
    sq += d * d;
  }
}

// Calls fn(tile) for the block's valid spectra in tiles of up to kTile rows (double, negatives clipped or
// refused); returns the number of negative values seen and adds the sum of squares of the clipped values to xx.
template <class Fn>
std::uint64_t for_each_tile(const BlockReader& reader, std::size_t block, const BlockReader::RawBlock& raw,
                            Negatives policy, RowMatrixXd& tile, Fn&& fn, std::size_t ld = 0, double* xx = nullptr) {
  const std::size_t b = reader.bands();
  if (ld < b) ld = b;
  if (std::size_t(tile.rows()) != kTile || std::size_t(tile.cols()) != ld)
    tile = RowMatrixXd::Zero(Eigen::Index(kTile), Eigen::Index(ld));  // columns beyond b stay zero
  std::uint64_t negatives = 0;
  double sq = 0;
  std::size_t fill = 0;
  for (std::size_t p = 0; p < raw.pixels; ++p) {
    if (!raw.is_valid(p)) continue;
    unsigned bad = 0, neg = 0;
    clip_spectrum(raw.spectrum(p, b), b, tile.data() + fill * ld, bad, neg, sq);
    negatives += neg;
    if (bad || (neg && policy == Negatives::reject)) {
      throw InputError(reader.describe_block(block) + ": spectrum " + std::to_string(p) + " of the block" +
                       (bad ? " has a non-finite value; NMF needs finite data (re-import, or mask the pixel)"
                            : " has a negative value; rerun with negatives = clip to clip such values to zero"));
    }
    if (++fill == kTile) {
      fn(tile.topRows(Eigen::Index(fill)));
      fill = 0;
    }
  }
  if (fill) fn(tile.topRows(Eigen::Index(fill)));
  if (xx) *xx += sq;
  return negatives;
}

// Small products of the coefficient pass for k <= 8 (coefficients padded to 8), on tiles whose rows are
// padded to a multiple of 4 with zeros. AVX2 register blocks where available, plain loops otherwise.
constexpr std::size_t kPad = 8;

// h (n x 8) = X (n x ld) * st (ld x 8).
void times_basis(const double* x, std::size_t n, std::size_t ld, const double* st, double* h) {
  std::size_t r = 0;
#if defined(__AVX2__) && defined(__FMA__)
  for (; r + 4 <= n; r += 4) {
    __m256d a00 = _mm256_setzero_pd(), a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00, a30 = a00, a31 = a00;
    const double* x0 = x + r * ld;
    for (std::size_t b = 0; b < ld; ++b) {
      const __m256d s0 = _mm256_loadu_pd(st + b * kPad), s1 = _mm256_loadu_pd(st + b * kPad + 4);
      __m256d v = _mm256_broadcast_sd(x0 + b);
      a00 = _mm256_fmadd_pd(v, s0, a00);
      a01 = _mm256_fmadd_pd(v, s1, a01);
      v = _mm256_broadcast_sd(x0 + ld + b);
      a10 = _mm256_fmadd_pd(v, s0, a10);
      a11 = _mm256_fmadd_pd(v, s1, a11);
      v = _mm256_broadcast_sd(x0 + 2 * ld + b);
      a20 = _mm256_fmadd_pd(v, s0, a20);
      a21 = _mm256_fmadd_pd(v, s1, a21);
      v = _mm256_broadcast_sd(x0 + 3 * ld + b);
      a30 = _mm256_fmadd_pd(v, s0, a30);
      a31 = _mm256_fmadd_pd(v, s1, a31);
    }
    double* o = h + r * kPad;
    _mm256_storeu_pd(o, a00);
    _mm256_storeu_pd(o + 4, a01);
    _mm256_storeu_pd(o + 8, a10);
    _mm256_storeu_pd(o + 12, a11);
    _mm256_storeu_pd(o + 16, a20);
    _mm256_storeu_pd(o + 20, a21);
    _mm256_storeu_pd(o + 24, a30);
    _mm256_storeu_pd(o + 28, a31);
  }
#endif
  for (; r < n; ++r) {
    double acc[kPad] = {};
    for (std::size_t b = 0; b < ld; ++b)
      for (std::size_t j = 0; j < kPad; ++j) acc[j] += x[r * ld + b] * st[b * kPad + j];
    std::copy(acc, acc + kPad, h + r * kPad);
  }
}

// out (rows x 8) += sum over t < n of a_t (row t of a, length rows, a multiple of 4) times c_t (row t of c, 8).
void outer_accumulate(const double* a, std::size_t lda, std::size_t rows, const double* c, std::size_t n, double* out) {
  for (std::size_t i0 = 0; i0 < rows; i0 += 4) {
#if defined(__AVX2__) && defined(__FMA__)
    __m256d a00 = _mm256_setzero_pd(), a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00, a30 = a00, a31 = a00;
    for (std::size_t t = 0; t < n; ++t) {
      const double* ct = c + t * kPad;
      const double* at = a + t * lda + i0;
      const __m256d c0 = _mm256_loadu_pd(ct), c1 = _mm256_loadu_pd(ct + 4);
      __m256d v = _mm256_broadcast_sd(at);
      a00 = _mm256_fmadd_pd(v, c0, a00);
      a01 = _mm256_fmadd_pd(v, c1, a01);
      v = _mm256_broadcast_sd(at + 1);
      a10 = _mm256_fmadd_pd(v, c0, a10);
      a11 = _mm256_fmadd_pd(v, c1, a11);
      v = _mm256_broadcast_sd(at + 2);
      a20 = _mm256_fmadd_pd(v, c0, a20);
      a21 = _mm256_fmadd_pd(v, c1, a21);
      v = _mm256_broadcast_sd(at + 3);
      a30 = _mm256_fmadd_pd(v, c0, a30);
      a31 = _mm256_fmadd_pd(v, c1, a31);
    }
    double* o = out + i0 * kPad;
    const __m256d acc[8] = {a00, a01, a10, a11, a20, a21, a30, a31};
    for (std::size_t q = 0; q < 8; ++q) _mm256_storeu_pd(o + 4 * q, _mm256_add_pd(_mm256_loadu_pd(o + 4 * q), acc[q]));
#else
    for (std::size_t t = 0; t < n; ++t)
      for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = 0; j < kPad; ++j) out[(i0 + i) * kPad + j] += a[t * lda + i0 + i] * c[t * kPad + j];
#endif
  }
}

struct GramStats {
  Eigen::MatrixXd gram;
  std::uint64_t n = 0, negatives = 0;
  template <class F, class G>
  void fields(F&& f, G&& g) {
    f(gram.data(), std::size_t(gram.size()));
    g(n);
    g(negatives);
  }
  GramStats& operator+=(const GramStats& o) {
    gram += o.gram;
    n += o.n;
    negatives += o.negatives;
    return *this;
  }
};

struct SignStats {
  Eigen::VectorXd pos, neg;
  template <class F, class G>
  void fields(F&& f, G&&) {
    f(pos.data(), std::size_t(pos.size()));
    f(neg.data(), std::size_t(neg.size()));
  }
  SignStats& operator+=(const SignStats& o) {
    pos += o.pos;
    neg += o.neg;
    return *this;
  }
};

struct EpochStats {
  Eigen::MatrixXd ctc, ctx;  // C^T C (k x k), C^T X (k x B)
  double xx = 0;
  std::uint64_t unconverged = 0;
  template <class F, class G>
  void fields(F&& f, G&& g) {
    f(ctc.data(), std::size_t(ctc.size()));
    f(ctx.data(), std::size_t(ctx.size()));
    f(&xx, 1);
    g(unconverged);
  }
  EpochStats& operator+=(const EpochStats& o) {
    ctc += o.ctc;
    ctx += o.ctx;
    xx += o.xx;
    unconverged += o.unconverged;
    return *this;
  }
};

GramStats gram_pass(const Collective& ranks, const BlockReader& reader, Negatives policy) {
  const auto b = Eigen::Index(reader.bands());
  GramStats zero{Eigen::MatrixXd::Zero(b, b)};
  GramStats s = reduce_blocks(ranks, reader, zero, "nmf: X^T X",
                              [&](std::size_t i, const BlockReader::RawBlock& raw, GramStats& out) {
                                thread_local RowMatrixXd tile;
                                out.negatives += for_each_tile(reader, i, raw, policy, tile, [&](const auto& t) {
                                  out.gram.selfadjointView<Eigen::Lower>().rankUpdate(t.transpose());
                                  out.n += std::uint64_t(t.rows());
                                });
                              });
  s.gram.triangularView<Eigen::StrictlyUpper>() = s.gram.transpose();
  return s;
}

// Coefficients of the spectra of blocks [first, last) for `basis` (exact NNLS) and their statistics.
EpochStats coefficient_pass(const Collective& ranks, const BlockReader& reader, const Eigen::MatrixXd& basis,
                            Negatives policy, std::size_t first, std::size_t last, Progress& progress,
                            std::size_t stride = 1) {
  const Eigen::Index k = basis.rows(), b = basis.cols();
  const GramNnls solver(basis * basis.transpose());
  const EpochStats zero{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
  if (std::size_t(k) <= kPad) {
    // Fast path: coefficients padded to 8, tile rows to a multiple of 4; per-block sums in padded form.
    const std::size_t ld = (std::size_t(b) + 3) / 4 * 4;
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> st =
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>::Zero(Eigen::Index(ld),
                                                                                     Eigen::Index(kPad));
    st.topLeftCorner(b, k) = basis.transpose();
    return reduce_range(
        ranks, reader, zero, first, last, progress,
        [&](std::size_t i, const BlockReader::RawBlock& raw, EpochStats& out) {
          thread_local RowMatrixXd tile;
          thread_local std::vector<double> h, c, ctx, ctc;
          h.assign(kTile * kPad, 0.0);
          c.assign(kTile * kPad, 0.0);  // entries beyond k stay zero
          ctx.assign(ld * kPad, 0.0);
          ctc.assign(kPad * kPad, 0.0);
          std::uint64_t hint = 0;  // neighbouring spectra usually share their passive set
          for_each_tile(
              reader, i, raw, policy, tile,
              [&](const auto& t) {
                const std::size_t n = std::size_t(t.rows());
                times_basis(t.data(), n, ld, st.data(), h.data());
                for (std::size_t r = 0; r < n; ++r) {
                  const NnlsStatus s = solver.solve(h.data() + r * kPad, c.data() + r * kPad, hint);
                  out.unconverged += !s.converged;
                }
                outer_accumulate(t.data(), ld, ld, c.data(), n, ctx.data());
                outer_accumulate(c.data(), kPad, kPad, c.data(), n, ctc.data());
              },
              ld, &out.xx);
          for (Eigen::Index p = 0; p < k; ++p) {
            for (Eigen::Index q = 0; q < k; ++q) out.ctc(p, q) += ctc[std::size_t(p) * kPad + std::size_t(q)];
            for (Eigen::Index j = 0; j < b; ++j) out.ctx(p, j) += ctx[std::size_t(j) * kPad + std::size_t(p)];
          }
        },
        stride);
  }
  return reduce_range(
      ranks, reader, zero, first, last, progress,
      [&](std::size_t i, const BlockReader::RawBlock& raw, EpochStats& out) {
        thread_local RowMatrixXd tile, h, c;
        std::uint64_t hint = 0;
        for_each_tile(
            reader, i, raw, policy, tile,
            [&](const auto& t) {
              h.noalias() = t * basis.transpose();
              c.resize(t.rows(), k);
              for (Eigen::Index r = 0; r < t.rows(); ++r) {
                const NnlsStatus st = solver.solve(h.data() + r * k, c.data() + r * k, hint);
                out.unconverged += !st.converged;
              }
              out.ctc.noalias() += c.transpose() * c;
              out.ctx.noalias() += c.transpose() * t;
            },
            0, &out.xx);
      },
      stride);
}

// The exact S step: min_{S >= 0} ||X - C S||^2 given C^T C and C^T X, one NNLS per band.
Eigen::MatrixXd solve_basis(const EpochStats& s) {
  const GramNnls solver(s.ctc);
  const Eigen::Index k = s.ctc.rows(), b = s.ctx.cols();
  Eigen::MatrixXd out(k, b);
  Eigen::VectorXd h(k), c(k);
  for (Eigen::Index j = 0; j < b; ++j) {
    h = s.ctx.col(j);
    solver.solve(h.data(), c.data());
    out.col(j) = c;
  }
  return out;
}

double certified_error(const EpochStats& s, const Eigen::MatrixXd& basis) {
  const double err2 =
      s.xx - 2 * (s.ctx.array() * basis.array()).sum() + (s.ctc.array() * (basis * basis.transpose()).array()).sum();
  return s.xx > 0 ? std::sqrt(std::max(0.0, err2) / s.xx) : 0.0;
}

Eigen::RowVectorXd random_row(Eigen::Index b, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::RowVectorXd r(b);
  for (Eigen::Index j = 0; j < b; ++j) r[j] = u(rng);
  return r;
}

// Rows scaled to unit norm; returns the factors d (row i divided by d_i). A row that died (all zero) is
// restarted from a seeded random spectrum (d_i = 1).
Eigen::VectorXd normalise_rows(Eigen::MatrixXd& s, std::mt19937_64& rng) {
  Eigen::VectorXd d = Eigen::VectorXd::Ones(s.rows());
  for (Eigen::Index i = 0; i < s.rows(); ++i) {
    double norm = s.row(i).norm();
    if (!(norm > 0)) {
      s.row(i) = random_row(s.cols(), rng);
      s.row(i) /= s.row(i).norm();
      continue;
    }
    s.row(i) /= norm;
    d[i] = norm;
  }
  return d;
}

// Statistics of coefficients C D (when the basis rows were divided by d): C^T C -> D C^T C D, C^T X -> D C^T X.
void rescale(EpochStats& s, const Eigen::VectorXd& d) {
  s.ctc = d.asDiagonal() * s.ctc * d.asDiagonal();
  s.ctx = d.asDiagonal() * s.ctx;
}

Eigen::MatrixXd random_init(Eigen::Index k, Eigen::Index b, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Eigen::MatrixXd s(k, b);
  for (Eigen::Index i = 0; i < k; ++i) s.row(i) = random_row(b, rng);
  normalise_rows(s, rng);
  return s;
}

// NNDSVD (Boutsidis and Gallopoulos 2008) for the basis factor: the top k right singular vectors v_j of X,
// each split into its positive and negative parts; the part whose product with the norm of the matching part
// of u_j = X v_j / sigma_j is larger is kept. The u norms take one more pass.
Eigen::MatrixXd nndsvd_init(const Collective& ranks, const BlockReader& reader, const Eigen::MatrixXd& gram,
                            Eigen::Index k, Negatives policy, std::uint64_t seed, std::size_t& passes) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  const Eigen::Index b = gram.rows();
  Eigen::MatrixXd v(b, k);
  for (Eigen::Index j = 0; j < k; ++j) v.col(j) = eig.eigenvectors().col(b - 1 - j);
  const SignStats zero{Eigen::VectorXd::Zero(k), Eigen::VectorXd::Zero(k)};
  const SignStats signs = reduce_blocks(ranks, reader, zero, "nmf: nndsvd",
                                        [&](std::size_t i, const BlockReader::RawBlock& raw, SignStats& out) {
                                          thread_local RowMatrixXd tile, u;
                                          for_each_tile(reader, i, raw, policy, tile, [&](const auto& t) {
                                            u.noalias() = t * v;
                                            out.pos += u.cwiseMax(0.0).colwise().squaredNorm().transpose();
                                            out.neg += u.cwiseMin(0.0).colwise().squaredNorm().transpose();
                                          });
                                        });
  ++passes;
  std::mt19937_64 rng(seed);
  Eigen::MatrixXd s(k, b);
  for (Eigen::Index j = 0; j < k; ++j) {
    const Eigen::VectorXd vp = v.col(j).cwiseMax(0.0), vn = (-v.col(j)).cwiseMax(0.0);
    const double mp = std::sqrt(signs.pos[j]) * vp.norm(), mn = std::sqrt(signs.neg[j]) * vn.norm();
    s.row(j) = (mp >= mn ? vp : vn).transpose();
  }
  normalise_rows(s, rng);
  return s;
}

std::string fingerprint(const BlockReader& reader, const NmfOptions& o) {
  std::ostringstream f;
  f << "k=" << o.k << " init=" << (o.init == Init::nndsvd ? "nndsvd" : "random") << " seed=" << o.seed
    << " restarts=" << o.restarts << " warmup_blocks=" << o.warmup_blocks << " wave_blocks=" << o.wave_blocks
    << " negatives=" << (o.negatives == Negatives::clip ? "clip" : "reject") << " bands=" << reader.bands()
    << " spectra=" << reader.spectra() << " blocks=" << reader.block_count() << " sources=";
  for (const auto& n : reader.source_names()) f << n << ",";
  return f.str();
}

std::string describe_difference(const std::string& a, const std::string& b) {
  std::istringstream sa(a), sb(b);
  std::string x, y, out;
  while (sa >> x && sb >> y)
    if (x != y) out += (out.empty() ? "" : ", ") + y + " (checkpoint: " + x + ")";
  return out.empty() ? "the runs differ" : out;
}

}  // namespace

Init parse_init(const std::string& s) {
  if (s == "nndsvd") return Init::nndsvd;
  if (s == "random") return Init::random;
  throw UsageError("init '" + s + "': choose nndsvd or random");
}

Negatives parse_negatives(const std::string& s) {
  if (s == "clip") return Negatives::clip;
  if (s == "reject") return Negatives::reject;
  throw UsageError("negatives '" + s + "': choose clip (clip to zero and count) or reject");
}

std::pair<double, double> basis_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.rows() == 0)
    throw UsageError("basis_angles: bases of different shapes");
  const Eigen::Index k = a.rows();
  Eigen::MatrixXd cosine(k, k);
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index j = 0; j < k; ++j) {
      const double na = a.row(i).norm(), nb = b.row(j).norm();
      cosine(i, j) = na > 0 && nb > 0 ? std::clamp(a.row(i).dot(b.row(j)) / (na * nb), -1.0, 1.0) : 0.0;
    }
  std::vector<Eigen::Index> perm(static_cast<std::size_t>(k)), best;
  std::iota(perm.begin(), perm.end(), Eigen::Index(0));
  if (k <= 8) {
    double best_sum = -1e300;
    do {
      double sum = 0;
      for (Eigen::Index i = 0; i < k; ++i) sum += cosine(i, perm[std::size_t(i)]);
      if (sum > best_sum) {
        best_sum = sum;
        best = perm;
      }
    } while (std::next_permutation(perm.begin(), perm.end()));
  } else {
    best.assign(std::size_t(k), -1);
    std::vector<bool> used_a(static_cast<std::size_t>(k)), used_b(static_cast<std::size_t>(k));
    for (Eigen::Index step = 0; step < k; ++step) {
      Eigen::Index bi = -1, bj = -1;
      for (Eigen::Index i = 0; i < k; ++i)
        for (Eigen::Index j = 0; j < k; ++j)
          if (!used_a[std::size_t(i)] && !used_b[std::size_t(j)] && (bi < 0 || cosine(i, j) > cosine(bi, bj))) {
            bi = i;
            bj = j;
          }
      used_a[std::size_t(bi)] = used_b[std::size_t(bj)] = true;
      best[std::size_t(bi)] = bj;
    }
  }
  double sum = 0, worst = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    const double deg = std::acos(cosine(i, best[std::size_t(i)])) * 180.0 / M_PI;
    sum += deg;
    worst = std::max(worst, deg);
  }
  return {sum / double(k), worst};
}

NmfResult factorize(const BlockReader& reader, const NmfOptions& o, const Collective& ranks) {
  const auto b = Eigen::Index(reader.bands());
  const auto k = Eigen::Index(o.k);
  if (o.k < 1 || o.k > reader.bands())
    throw UsageError("k = " + std::to_string(o.k) + ": give between 1 and " + std::to_string(reader.bands()) +
                     " components (the data has " + std::to_string(reader.bands()) + " bands)");
  if (o.restarts < 1 || o.restarts > 1000)
    throw UsageError("restarts " + std::to_string(o.restarts) + ": give 1 to 1000");
  if (o.max_epochs < 1) throw UsageError("max_epochs must be at least 1");
  if (o.wave_blocks < 1 || o.wave_blocks > 1000000)
    throw UsageError("wave_blocks " + std::to_string(o.wave_blocks) + ": give 1 to 1000000 blocks per basis update");
  if (!(o.tol >= 0) || !std::isfinite(o.tol)) throw UsageError("tol must be a finite number >= 0");
  if (reader.spectra() == 0) throw InputError("the selection holds no valid spectra");
  if (o.resume && o.checkpoint.empty()) throw UsageError("resume needs a checkpoint path");
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };

  NmfResult result;
  const std::string print = fingerprint(reader, o);
  Checkpoint cp;
  bool resumed = false;
  if (o.resume) {
    cp = load_checkpoint(o.checkpoint);
    if (cp.fingerprint != print)
      throw UsageError(o.checkpoint.string() +
                       ": the checkpoint is of another run: " + describe_difference(cp.fingerprint, print) +
                       "; rerun with the same options, or start afresh instead of resuming");
    resumed = true;
  } else {
    const GramStats g = gram_pass(ranks, reader, o.negatives);
    ++result.passes;
    cp.fingerprint = print;
    cp.gram = g.gram;
    cp.n = g.n;
    cp.negatives = g.negatives;
    cp.values = g.n * std::uint64_t(b);
  }
  result.resumed = resumed;
  result.n = cp.n;
  result.negatives = cp.negatives;
  result.values = cp.values;
  result.second_moment = cp.gram / double(std::max<std::uint64_t>(cp.n, 1));
  {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cp.gram, Eigen::EigenvaluesOnly);
    const Eigen::VectorXd ev = eig.eigenvalues().cwiseMax(0.0);  // ascending
    const double total = ev.sum();
    result.svd_bound = total > 0 ? std::sqrt(ev.head(b - k).sum() / total) : 0.0;
  }

  for (std::size_t r = 0; r < cp.done_bases.size(); ++r) {
    RestartResult rr;
    rr.basis = cp.done_bases[r];
    rr.history = cp.done_histories[r];
    rr.epochs = rr.history.size();
    rr.rel_error = rr.history.empty() ? 1.0 : rr.history.back();
    rr.converged = cp.done_converged[r] != 0;
    result.restarts.push_back(std::move(rr));
  }
  const std::size_t wave = o.wave_blocks;
  const std::size_t n_waves = (reader.block_count() + wave - 1) / wave;
  try {
    for (std::size_t r = cp.restart; r < o.restarts; ++r) {
      Eigen::MatrixXd s;
      std::vector<double> history;
      if (resumed && r == cp.restart && cp.epoch > 0) {
        s = cp.basis;
        history = cp.history;
        if (s.rows() != k || s.cols() != b)
          throw InputError(o.checkpoint.string() +
                           ": checkpoint basis has the wrong shape; delete it and start afresh");
      } else if (r == 0 && o.init == Init::nndsvd) {
        s = nndsvd_init(ranks, reader, cp.gram, k, o.negatives, o.seed, result.passes);
      } else {
        s = random_init(k, b, o.seed + r);
      }
      std::mt19937_64 rng(o.seed * 1000003 + r);
      bool converged = false;
      // Block-coordinate descent in waves: each wave's coefficients are solved exactly for the current basis,
      // then the basis is solved exactly from every wave's latest statistics. Those statistics are exact for
      // the coefficients currently held (implicitly) for every spectrum, so the error they give is certified
      // and never increases. A resumed run restarts from the epoch's end, where all waves are current.
      std::vector<EpochStats> waves(n_waves, EpochStats{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)});
      std::vector<char> seen(n_waves, 0);
      if (resumed && r == cp.restart && cp.epoch > 0) {
        if (cp.wave_xx.size() != n_waves)
          throw InputError(o.checkpoint.string() + ": checkpoint holds " + std::to_string(cp.wave_xx.size()) +
                           " waves, this run has " + std::to_string(n_waves) + "; delete it and start afresh");
        for (std::size_t w = 0; w < n_waves; ++w) {
          waves[w].ctc = Eigen::Map<const Eigen::MatrixXd>(cp.wave_ctc.row(Eigen::Index(w)).data(), k, k);
          waves[w].ctx = Eigen::Map<const Eigen::MatrixXd>(cp.wave_ctx.row(Eigen::Index(w)).data(), k, b);
          waves[w].xx = cp.wave_xx[w];
          seen[w] = 1;
        }
      }
      auto total_of = [&] {
        EpochStats t{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
        for (std::size_t w = 0; w < n_waves; ++w)
          if (seen[w]) t += waves[w];
        return t;
      };
      // One epoch of block-coordinate descent over the blocks first, first + stride, ... in waves of `wave` blocks.
      auto run_epoch = [&](std::vector<EpochStats>& ws, std::vector<char>& on, std::size_t step, Progress& progress) {
        for (std::size_t w = 0; w < ws.size(); ++w) {
          const std::size_t first = w * wave * step;
          const std::size_t last = std::min(reader.block_count(), first + wave * step);
          ws[w] = coefficient_pass(ranks, reader, s, o.negatives, first, last, progress, step);
          on[w] = 1;
          result.nnls_unconverged += ws[w].unconverged;
          EpochStats t{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
          for (std::size_t v = 0; v < ws.size(); ++v)
            if (on[v]) t += ws[v];
          s = solve_basis(t);
          const Eigen::VectorXd d = normalise_rows(s, rng);
          for (std::size_t v = 0; v < ws.size(); ++v)
            if (on[v]) rescale(ws[v], d);
        }
      };
      // Warm-up on a sample of whole blocks (every stride-th, about warmup_blocks of them) when the data is
      // large: the same descent on the sample until it stalls moves the basis close to its optimum at a small
      // fraction of a pass, so the full epochs start near it. Skipped on resume.
      const std::size_t stride = o.warmup_blocks ? reader.block_count() / o.warmup_blocks : 0;
      if (stride >= 2 && history.empty()) {
        const std::size_t sample = (reader.block_count() + stride - 1) / stride;
        std::vector<EpochStats> ws((sample + wave - 1) / wave,
                                   EpochStats{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)});
        std::vector<char> on(ws.size(), 0);
        double prev = std::numeric_limits<double>::infinity();
        for (std::size_t e = 0; e < kWarmupEpochs; ++e) {
          Progress progress("nmf: restart " + std::to_string(r + 1) + " warm-up " + std::to_string(e + 1),
                            reader.spectra() / stride);
          run_epoch(ws, on, stride, progress);
          EpochStats t{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
          for (const auto& x : ws) t += x;
          const double err = certified_error(t, s);
          result.warmup_epochs = e + 1;
          result.warmup_pass_equivalent += double(sample) / double(reader.block_count());
          if (prev - err <= 1e-4 * err) break;
          prev = err;
        }
        result.warmup_blocks = sample;
      }
      while (history.size() < o.max_epochs) {
        const std::size_t epoch = history.size() + 1;
        Progress progress("nmf: restart " + std::to_string(r + 1) + " epoch " + std::to_string(epoch),
                          reader.spectra());
        run_epoch(waves, seen, 1, progress);
        ++result.passes;
        const double err = certified_error(total_of(), s);
        const double prev = history.empty() ? std::numeric_limits<double>::infinity() : history.back();
        history.push_back(err);
        if (o.on_epoch) o.on_epoch({r, epoch, err, elapsed()});
        cp.restart = r;
        cp.epoch = history.size();
        cp.basis = s;
        cp.history = history;
        cp.wave_ctc.resize(Eigen::Index(n_waves), k * k);
        cp.wave_ctx.resize(Eigen::Index(n_waves), k * b);
        cp.wave_xx.resize(n_waves);
        for (std::size_t w = 0; w < n_waves; ++w) {
          cp.wave_ctc.row(Eigen::Index(w)) = Eigen::Map<const Eigen::RowVectorXd>(waves[w].ctc.data(), k * k);
          cp.wave_ctx.row(Eigen::Index(w)) = Eigen::Map<const Eigen::RowVectorXd>(waves[w].ctx.data(), k * b);
          cp.wave_xx[w] = waves[w].xx;
        }
        if (!o.checkpoint.empty() && ranks.rank() == 0) save_checkpoint(o.checkpoint, cp);
        if (prev - err <= o.tol * err) {
          converged = true;
          break;
        }
        check_interrupt();
      }
      RestartResult rr;
      rr.basis = s;
      rr.history = history;
      rr.epochs = history.size();
      rr.rel_error = history.back();
      rr.converged = converged;
      result.restarts.push_back(rr);
      cp.done_bases.push_back(s);
      cp.done_histories.push_back(history);
      cp.done_converged.push_back(converged);
      cp.restart = r + 1;
      cp.epoch = 0;
      cp.history.clear();
      cp.wave_ctc.resize(0, 0);
      cp.wave_ctx.resize(0, 0);
      cp.wave_xx.clear();
      cp.basis = s;
      if (!o.checkpoint.empty() && ranks.rank() == 0 && r + 1 < o.restarts) save_checkpoint(o.checkpoint, cp);
    }
  } catch (const Interrupted&) {
    const std::string kept = std::to_string(cp.epoch) + " finished epoch" + (cp.epoch == 1 ? "" : "s") +
                             " of restart " + std::to_string(cp.restart + 1);
    throw Interrupted("interrupted; " + (o.checkpoint.empty() ? kept + " were not saved (no checkpoint)"
                                                              : kept + " kept in " + o.checkpoint.string() +
                                                                    ": resume from it to continue"));
  }
  std::size_t best = 0;
  for (std::size_t r = 1; r < result.restarts.size(); ++r)
    if (result.restarts[r].rel_error < result.restarts[best].rel_error) best = r;
  result.best = best;
  for (auto& rr : result.restarts)
    std::tie(rr.mean_angle_deg, rr.max_angle_deg) = basis_angles(rr.basis, result.restarts[best].basis);
  // The certifying pass: the best basis's exact coefficients give its own error and the RMS coefficient of
  // each component.
  Progress progress("nmf: certifying pass", reader.spectra());
  EpochStats fin{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
  const Share share = share_of(ranks, reader.block_count());
  for (std::size_t first = share.first; first < share.last; first += kRangeBlocks)
    fin += coefficient_pass(single_process(), reader, result.restarts[best].basis, o.negatives, first,
                            std::min(share.last, first + kRangeBlocks), progress);
  sum_over_ranks(ranks, fin);
  ++result.passes;
  result.nnls_unconverged += fin.unconverged;
  result.rel_error = certified_error(fin, result.restarts[best].basis);
  result.weights = (fin.ctc.diagonal() / double(std::max<std::uint64_t>(result.n, 1))).cwiseSqrt();
  return result;
}

}  // namespace specula::nmf
