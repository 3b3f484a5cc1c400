#include "stats/moments.h"

#include <omp.h>

#include <exception>
#include <mutex>
#include <optional>

#include "core/error.h"
#include "core/interrupt.h"

namespace specula::stats {
namespace {

// The moments of one block: its mean and centred Gram, computed in double from float32 or float64 rows.
template <class Block>
Moments block_moments(const Block& x, std::size_t bands) {
  thread_local RowMatrixXd centred;
  Moments m(bands);
  if (x.rows() == 0) return m;
  const Eigen::RowVectorXd mean = x.template cast<double>().colwise().sum() / double(x.rows());
  centred = x.template cast<double>().rowwise() - mean;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(Eigen::Index(bands), Eigen::Index(bands));
  gram.selfadjointView<Eigen::Lower>().rankUpdate(centred.transpose());
  gram.triangularView<Eigen::StrictlyUpper>() = gram.transpose();
  m.merge_raw(std::uint64_t(x.rows()), mean.transpose(), gram);
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
