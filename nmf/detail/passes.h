#pragma once
// Inside nmf/ only: the passes over the data that factorize() is built from (X^T X, the exact coefficients of a
// basis and their statistics), the exact basis step and the initial bases. Every pass's result is the same for any
// thread count and, under several ranks, summed in rank order.
#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "specula/core/collective.h"
#include "specula/core/progress.h"
#include "specula/nmf/nmf.h"
#include "specula/store/block_reader.h"

namespace specula::nmf::detail {

using store::BlockReader;

// Blocks per range of a pass that needs no basis updates (memory per thread grows with it).
constexpr std::size_t kRangeBlocks = 32;

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

/// X^T X of the selection (negatives clipped or refused by `policy`), with the spectrum and negative counts.
GramStats gram_pass(const Collective& ranks, const BlockReader& reader, Negatives policy);
/// Coefficients of the spectra of blocks first, first + stride, ... below last for `basis` (exact NNLS) and their
/// statistics.
EpochStats coefficient_pass(const Collective& ranks, const BlockReader& reader, const Eigen::MatrixXd& basis,
                            Negatives policy, std::size_t first, std::size_t last, Progress& progress,
                            std::size_t stride = 1);
/// The exact S step: min_{S >= 0} ||X - C S||^2 given C^T C and C^T X, one NNLS per band.
Eigen::MatrixXd solve_basis(const EpochStats& s);
/// The relative error ||X - C S|| / ||X|| that the statistics certify for `basis`.
double certified_error(const EpochStats& s, const Eigen::MatrixXd& basis);
/// Rows scaled to unit norm; returns the factors d (row i divided by d_i). A row that died (all zero) is
/// restarted from a seeded random spectrum (d_i = 1).
Eigen::VectorXd normalise_rows(Eigen::MatrixXd& s, std::mt19937_64& rng);
/// Statistics of coefficients C D (when the basis rows were divided by d): C^T C -> D C^T C D, C^T X -> D C^T X.
void rescale(EpochStats& s, const Eigen::VectorXd& d);
/// A seeded random k x b basis of unit rows.
Eigen::MatrixXd random_init(Eigen::Index k, Eigen::Index b, std::uint64_t seed);
/// The NNDSVD basis from X^T X (one more pass over the data, counted in `passes`).
Eigen::MatrixXd nndsvd_init(const Collective& ranks, const BlockReader& reader, const Eigen::MatrixXd& gram,
                            Eigen::Index k, Negatives policy, std::uint64_t seed, std::size_t& passes);

}  // namespace specula::nmf::detail
