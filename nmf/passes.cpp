// The passes over the data behind factorize() (nmf/detail/passes.h): block reductions summed in block order,
// spectra clipped in tiles, the coefficient kernels for small k, the basis step and the initial bases.
#include "specula/nmf/detail/passes.h"

#include <immintrin.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/nnls.h"
#include "specula/core/parallel.h"

namespace specula::nmf::detail {
namespace {

constexpr std::size_t kTile = 256;

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

Eigen::RowVectorXd random_row(Eigen::Index b, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::RowVectorXd r(b);
  for (Eigen::Index j = 0; j < b; ++j) r[j] = u(rng);
  return r;
}

}  // namespace

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
                            std::size_t stride) {
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

}  // namespace specula::nmf::detail
