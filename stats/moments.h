#pragma once
// Exact streaming statistics of spectra: count, mean and centred scatter, merged with the update of
// Chan, Golub & LeVeque (1979), so the covariance of billions of spectra is as accurate as a two-pass
// computation and never needs E[x x^T] - mu mu^T (which cancels catastrophically).
#include <Eigen/Core>
#include <cstdint>

#include "specula/core/collective.h"
#include "specula/core/colour.h"
#include "specula/store/block_reader.h"

namespace specula::stats {

class Moments {
 public:
  Moments() = default;
  /// Empty statistics over `bands` bands.
  explicit Moments(std::size_t bands);
  /// Adds the rows of `block` (n x B): the block's own mean and centred Gram in double, then a merge.
  void add(const Eigen::Ref<const RowMatrixXd>& block);
  /// Merges `other` into this; throws UsageError if the band counts differ.
  void merge(const Moments& other);

  std::uint64_t count() const { return n_; }
  std::size_t bands() const { return std::size_t(mean_.size()); }
  const Eigen::VectorXd& mean() const { return mean_; }
  /// Centred scatter sum (x - mean)(x - mean)^T.
  const Eigen::MatrixXd& scatter() const { return scatter_; }
  /// Sample covariance scatter / (n - 1); throws UsageError for fewer than two spectra.
  Eigen::MatrixXd covariance() const;
  /// Uncentred second moment E[x x^T] = scatter / n + mean mean^T.
  Eigen::MatrixXd second_moment() const;

  /// Merges statistics given as their parts (count, mean, centred scatter).
  void merge_raw(std::uint64_t n, const Eigen::VectorXd& mean, const Eigen::MatrixXd& scatter);

 private:
  std::uint64_t n_ = 0;
  Eigen::VectorXd mean_;
  Eigen::MatrixXd scatter_;
};

/// One pass over every block of `reader`: per-block moments merged in block order through a fixed binary
/// tree, so the result is bit-identical for any thread count; memory O(threads x bands^2), not O(N). Under
/// several ranks each reads a contiguous share of the blocks and the shares are merged in rank order on
/// every rank (equal to the one-process result up to rounding).
Moments stream_moments(const store::BlockReader& reader, const Collective& ranks = single_process());

}  // namespace specula::stats
