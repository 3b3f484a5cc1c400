#include "stats/moments.h"

#include <omp.h>

#include <exception>
#include <mutex>
#include <optional>

#include "core/error.h"
#include "core/interrupt.h"
#include "core/progress.h"

namespace specula::stats {
namespace {

// The moments of one block: its mean and centred Gram, computed in double from float32 or float64 rows.
// Adds the lower triangle of D D^T to gram, D being `rows` x `len` row-major with rows a multiple of 4:
// 4 x 2 blocks of dot products over contiguous rows (8 vector accumulators and 6 loads fit AVX2's 16
// registers), each block's sums vectorised along the row. Entries above the diagonal are not meaningful.
void gram_lower_add(const double* d, std::size_t rows, std::size_t len, double* gram, std::size_t ld) {
  for (std::size_t p = 0; p < rows; p += 4)
    for (std::size_t q = 0; q <= p + 2; q += 2) {
      const double *p0 = d + p * len, *p1 = p0 + len, *p2 = p1 + len, *p3 = p2 + len;
      const double *q0 = d + q * len, *q1 = q0 + len;
      double s00 = 0, s01 = 0, s10 = 0, s11 = 0, s20 = 0, s21 = 0, s30 = 0, s31 = 0;
#pragma omp simd reduction(+ : s00, s01, s10, s11, s20, s21, s30, s31)
      for (std::size_t j = 0; j < len; ++j) {
        s00 += p0[j] * q0[j]; s01 += p0[j] * q1[j];
        s10 += p1[j] * q0[j]; s11 += p1[j] * q1[j];
        s20 += p2[j] * q0[j]; s21 += p2[j] * q1[j];
        s30 += p3[j] * q0[j]; s31 += p3[j] * q1[j];
      }
      double* g = gram + p * ld + q;
      g[0] += s00; g[1] += s01;
      g[ld] += s10; g[ld + 1] += s11;
      g[2 * ld] += s20; g[2 * ld + 1] += s21;
      g[3 * ld] += s30; g[3 * ld + 1] += s31;
    }
}

// The moments of one block in one pass: deviations d = x - x0 from the block's first spectrum (the
// shifted-data algorithm; x0 lies within the data's spread, so sum(d d^T) - sum(d) sum(d)^T / n does not
// cancel badly), accumulated over 64-spectrum tiles (16 KB: they stay in L1).
template <class Block>
Moments block_moments(const Block& x, std::size_t bands) {
  Moments m(bands);
  if (x.rows() == 0) return m;
  const std::size_t b = bands, bp = (bands + 3) / 4 * 4;
  constexpr std::size_t kTile = 64;
  thread_local std::vector<double> tile, shift;
  tile.assign(bp * kTile, 0.0);  // padding rows stay zero
  shift.assign(b, 0.0);
  for (std::size_t k = 0; k < b; ++k) shift[k] = double(x(0, Eigen::Index(k)));
  std::vector<double> gram(bp * bp, 0.0);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Eigen::Index(b));
  const std::size_t rows = std::size_t(x.rows());
  for (std::size_t r0 = 0; r0 < rows; r0 += kTile) {
    const std::size_t n = std::min(kTile, rows - r0);
    // Transpose the tile into band rows (zero beyond n so a short last tile adds nothing).
    for (std::size_t i = 0; i < n; ++i) {
      const auto row = x.row(Eigen::Index(r0 + i));
      for (std::size_t k = 0; k < b; ++k) tile[k * kTile + i] = double(row(Eigen::Index(k))) - shift[k];
    }
    if (n < kTile)
      for (std::size_t k = 0; k < b; ++k) std::fill(tile.begin() + std::ptrdiff_t(k * kTile + n), tile.begin() + std::ptrdiff_t((k + 1) * kTile), 0.0);
    for (std::size_t k = 0; k < b; ++k) {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) s += tile[k * kTile + i];
      sum[Eigen::Index(k)] += s;
    }
    gram_lower_add(tile.data(), bp, kTile, gram.data(), bp);
  }
  const double n = double(rows);
  Eigen::MatrixXd scatter{Eigen::Index(b), Eigen::Index(b)};
  for (std::size_t p = 0; p < b; ++p)
    for (std::size_t q = 0; q <= p; ++q) {
      const double v = gram[p * bp + q] - sum[Eigen::Index(p)] * sum[Eigen::Index(q)] / n;
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
  merge(block_moments(block, bands()));
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

Moments stream_moments(const store::BlockReader& reader) {
  const std::size_t bands = reader.bands(), blocks = reader.block_count();
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
  for (std::size_t first = 0; first < blocks; first += wave) {
    const std::size_t n = std::min(wave, blocks - first);
    part.assign(n, Moments(bands));
    std::exception_ptr error;
    std::mutex error_mutex;
#pragma omp parallel
    {
      RowMatrixXf buffer;
#pragma omp for schedule(dynamic, 1)
      for (long long j = 0; j < static_cast<long long>(n); ++j) {
        try {
          check_interrupt();
          reader.read(first + std::size_t(j), buffer);
          part[std::size_t(j)] = block_moments(buffer, bands);
          progress.advance(std::uint64_t(buffer.rows()));
        } catch (...) {
          std::lock_guard lock(error_mutex);
          if (!error) error = std::current_exception();
        }
      }
    }
    if (error) std::rethrow_exception(error);
    for (auto& m : part) push(std::move(m));
  }
  Moments total(bands);
  for (std::size_t l = slots.size(); l-- > 0;)
    if (slots[l]) total.merge(*slots[l]);
  return total;
}

}  // namespace specula::stats
