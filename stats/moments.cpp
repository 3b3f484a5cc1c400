#include "specula/stats/moments.h"

#include <immintrin.h>
#include <omp.h>

#include <cstring>
#include <exception>
#include <mutex>
#include <optional>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::stats {
namespace {

// The moments of one block in one pass: deviations d = x - x0 from the block's first spectrum (the
// shifted-data algorithm; x0 lies within the data's spread, so sum(d d^T) - sum(d) sum(d)^T / n does not
// cancel badly). Spectra are converted to double in tiles of kTile rows of `ld` doubles (bands, then a
// constant 1 whose Gram row is sum(d), then zero padding to a multiple of 8), small enough for L1.
// The lower triangle of the tile's Gram is a sum of rank-1 updates computed in 4 x 8 register blocks:
// per spectrum 2 vector loads and 4 broadcasts feed 8 FMAs, so the kernel is bound by FMA throughput
// (a portable version for builds without AVX2 and FMA).
constexpr std::size_t kTile = 64;

#if defined(__AVX2__) && defined(__FMA__)
void gram_tile_add(const double* tile, std::size_t n, std::size_t ld, double* gram) {
  for (std::size_t i0 = 0; i0 < ld; i0 += 4)
    for (std::size_t j0 = 0; j0 <= i0; j0 += 8) {
      __m256d a00 = _mm256_setzero_pd(), a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00, a30 = a00, a31 = a00;
      const double* x = tile;
      for (std::size_t t = 0; t < n; ++t, x += ld) {
        const __m256d c0 = _mm256_loadu_pd(x + j0), c1 = _mm256_loadu_pd(x + j0 + 4);
        __m256d b = _mm256_broadcast_sd(x + i0);
        a00 = _mm256_fmadd_pd(b, c0, a00);
        a01 = _mm256_fmadd_pd(b, c1, a01);
        b = _mm256_broadcast_sd(x + i0 + 1);
        a10 = _mm256_fmadd_pd(b, c0, a10);
        a11 = _mm256_fmadd_pd(b, c1, a11);
        b = _mm256_broadcast_sd(x + i0 + 2);
        a20 = _mm256_fmadd_pd(b, c0, a20);
        a21 = _mm256_fmadd_pd(b, c1, a21);
        b = _mm256_broadcast_sd(x + i0 + 3);
        a30 = _mm256_fmadd_pd(b, c0, a30);
        a31 = _mm256_fmadd_pd(b, c1, a31);
      }
      double* g = gram + i0 * ld + j0;
      const __m256d acc[4][2] = {{a00, a01}, {a10, a11}, {a20, a21}, {a30, a31}};
      for (std::size_t r = 0; r < 4; ++r, g += ld) {
        _mm256_storeu_pd(g, _mm256_add_pd(_mm256_loadu_pd(g), acc[r][0]));
        _mm256_storeu_pd(g + 4, _mm256_add_pd(_mm256_loadu_pd(g + 4), acc[r][1]));
      }
    }
}
#else
void gram_tile_add(const double* tile, std::size_t n, std::size_t ld, double* gram) {
  for (std::size_t i0 = 0; i0 < ld; i0 += 4)
    for (std::size_t j0 = 0; j0 <= i0; j0 += 8) {
      double acc[4][8] = {};
      const double* x = tile;
      for (std::size_t t = 0; t < n; ++t, x += ld)
        for (std::size_t r = 0; r < 4; ++r)
#pragma omp simd
          for (std::size_t l = 0; l < 8; ++l) acc[r][l] += x[i0 + r] * x[j0 + l];
      for (std::size_t r = 0; r < 4; ++r)
        for (std::size_t l = 0; l < 8; ++l) gram[(i0 + r) * ld + j0 + l] += acc[r][l];
    }
}
#endif

// `rows_in` rows of `bands` values, `stride` apart; rows whose mask entry is zero are skipped (no mask: all).
template <class T>
Moments block_moments(const T* x, std::size_t stride, std::size_t rows_in, const std::uint8_t* mask,
                      std::size_t bands) {
  Moments m(bands);
  const std::size_t b = bands, ld = (bands + 1 + 7) / 8 * 8;
  std::size_t first = 0;
  while (first < rows_in && mask && !mask[first]) ++first;
  if (first == rows_in) return m;
  thread_local std::vector<double> tile, shift, gram;
  tile.assign(ld * kTile, 0.0);
  gram.assign(ld * ld, 0.0);
  shift.assign(ld, 0.0);
  for (std::size_t k = 0; k < b; ++k) shift[k] = double(x[first * stride + k]);
  for (std::size_t i = 0; i < kTile; ++i) tile[i * ld + b] = 1.0;
  std::size_t rows = 0, fill = 0;
  for (std::size_t r = first; r < rows_in; ++r) {
    if (mask && !mask[r]) continue;
    const T* row = x + r * stride;
    double* t = tile.data() + fill * ld;
#pragma omp simd
    for (std::size_t k = 0; k < b; ++k) t[k] = double(row[k]) - shift[k];
    if (++fill == kTile) {
      gram_tile_add(tile.data(), fill, ld, gram.data());
      rows += fill;
      fill = 0;
    }
  }
  if (fill) gram_tile_add(tile.data(), fill, ld, gram.data());
  rows += fill;
  const double n = double(rows);
  Eigen::VectorXd sum{Eigen::Index(b)};
  for (std::size_t k = 0; k < b; ++k) sum[Eigen::Index(k)] = gram[b * ld + k];
  Eigen::MatrixXd scatter{Eigen::Index(b), Eigen::Index(b)};
  for (std::size_t p = 0; p < b; ++p)
    for (std::size_t q = 0; q <= p; ++q) {
      const double v = gram[p * ld + q] - sum[Eigen::Index(p)] * sum[Eigen::Index(q)] / n;
      scatter(Eigen::Index(p), Eigen::Index(q)) = v;
      scatter(Eigen::Index(q), Eigen::Index(p)) = v;
    }
  const Eigen::Map<const Eigen::VectorXd> x0(shift.data(), Eigen::Index(b));
  m.merge_raw(std::uint64_t(rows), x0 + sum / n, scatter);
  return m;
}

}  // namespace

Moments::Moments(std::size_t bands)
    : mean_(Eigen::VectorXd::Zero(Eigen::Index(bands))),
      scatter_(Eigen::MatrixXd::Zero(Eigen::Index(bands), Eigen::Index(bands))) {}

void Moments::add(const Eigen::Ref<const RowMatrixXd>& block) {
  if (std::size_t(block.cols()) != bands())
    throw UsageError("Moments::add: block has " + std::to_string(block.cols()) + " bands, statistics have " +
                     std::to_string(bands()));
  if (block.rows() > 0)
    merge(block_moments(block.data(), std::size_t(block.outerStride()), std::size_t(block.rows()), nullptr, bands()));
}

void Moments::merge(const Moments& other) { merge_raw(other.n_, other.mean_, other.scatter_); }

void Moments::merge_raw(std::uint64_t nb, const Eigen::VectorXd& mean_b, const Eigen::MatrixXd& scatter_b) {
  if (mean_b.size() != mean_.size())
    throw UsageError("Moments::merge: " + std::to_string(mean_b.size()) + " bands into " +
                     std::to_string(mean_.size()));
  if (nb == 0) return;
  if (n_ == 0) {
    n_ = nb;
    mean_ = mean_b;
    scatter_ = scatter_b;
    return;
  }
  const double na = double(n_), nbd = double(nb), n = na + nbd;
  const Eigen::VectorXd delta = mean_b - mean_;
  mean_ += delta * (nbd / n);
  scatter_ += scatter_b;
  scatter_.noalias() += (na * nbd / n) * (delta * delta.transpose());
  n_ += nb;
}

Eigen::MatrixXd Moments::covariance() const {
  if (n_ < 2) throw UsageError("a covariance needs at least two spectra, got " + std::to_string(n_));
  return scatter_ / double(n_ - 1);
}

Eigen::MatrixXd Moments::second_moment() const {
  if (n_ == 0) throw UsageError("a second moment needs at least one spectrum");
  return scatter_ / double(n_) + mean_ * mean_.transpose();
}

Moments stream_moments(const store::BlockReader& reader, const Collective& ranks) {
  const std::size_t bands = reader.bands();
  const Share share = share_of(ranks, reader.block_count());
  // A binary counter of partial results: slot l holds the merge of 2^l consecutive blocks, so blocks are
  // always merged in the same tree whatever thread computed them, and at most log2(blocks) slots live.
  std::vector<std::optional<Moments>> slots;
  auto push = [&](Moments m) {
    std::size_t l = 0;
    for (; l < slots.size() && slots[l]; ++l) {
      Moments earlier = std::move(*slots[l]);
      slots[l].reset();
      earlier.merge(m);
      m = std::move(earlier);
    }
    if (l == slots.size()) slots.emplace_back();
    slots[l] = std::move(m);
  };
  const std::size_t wave = std::size_t(std::max(1, omp_get_max_threads())) * 8;
  Progress progress("covariance", reader.spectra());
  std::vector<Moments> part;
  for (std::size_t first = share.first; first < share.last; first += wave) {
    const std::size_t n = std::min(wave, share.last - first);
    part.assign(n, Moments(bands));
    parallel_for(
        n, [] { return store::BlockReader::RawBlock(); },
        [&](std::size_t j, store::BlockReader::RawBlock& raw) {
          const std::size_t block = first + j;
          reader.read_raw(block, raw);
          part[j] =
              block_moments(raw.values.data(), bands, raw.pixels, raw.mask.empty() ? nullptr : raw.mask.data(), bands);
          // A NaN or infinity anywhere in the block makes its mean non-finite.
          if (!part[j].mean().allFinite() || !part[j].scatter().allFinite())
            throw InputError(
                reader.describe_block(block) +
                ": a valid spectrum holds a non-finite value; PCA needs finite data (re-import, or mask the pixel)");
          progress.advance(std::uint64_t(raw.valid));
        });
    for (auto& m : part) push(std::move(m));
  }
  Moments total(bands);
  for (std::size_t l = slots.size(); l-- > 0;)
    if (slots[l]) total.merge(*slots[l]);
  if (ranks.size() == 1) return total;
  // Every rank's share merged in rank order, on every rank.
  const std::size_t len = 1 + bands + bands * bands;
  std::vector<double> mine(len), all(len * std::size_t(ranks.size()));
  mine[0] = double(total.count());
  std::copy(total.mean().data(), total.mean().data() + bands, mine.begin() + 1);
  std::copy(total.scatter().data(), total.scatter().data() + bands * bands, mine.begin() + 1 + std::ptrdiff_t(bands));
  ranks.allgather(mine, all);
  Moments merged(bands);
  for (std::size_t r = 0; r < std::size_t(ranks.size()); ++r) {
    const double* p = all.data() + r * len;
    merged.merge_raw(std::uint64_t(p[0]), Eigen::Map<const Eigen::VectorXd>(p + 1, Eigen::Index(bands)),
                     Eigen::Map<const Eigen::MatrixXd>(p + 1 + bands, Eigen::Index(bands), Eigen::Index(bands)));
  }
  return merged;
}

}  // namespace specula::stats
