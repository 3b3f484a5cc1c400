#pragma once
// Out-of-core non-negative matrix factorisation (reference §7.4): X (N spectra x B bands) ~ C S with k
// non-negative basis spectra S (k x B). Alternating non-negative least squares, streamed over the store:
// each epoch is one pass that solves every spectrum's coefficients exactly (GramNnls) for the current S and
// accumulates the sufficient statistics C^T C, C^T X and ||X||^2; S is then solved exactly from them (NNLS
// per band). The coefficients C (N x k) are never held. The error printed for an epoch is
// ||X - C S||_F / ||X||_F of that pass's C with the updated S, computed exactly from the statistics: a
// certified value, and it never increases from one epoch to the next.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "specula/core/collective.h"
#include "specula/store/block_reader.h"

namespace specula::nmf {

enum class Init { nndsvd, random };
/// Negative values (sensor noise below zero): clipped to zero and counted, or refused.
enum class Negatives { clip, reject };

/// Parses "nndsvd" or "random"; throws UsageError otherwise.
Init parse_init(const std::string& s);
/// Parses "clip" or "reject"; throws UsageError otherwise.
Negatives parse_negatives(const std::string& s);

/// One finished epoch.
struct EpochReport {
  std::size_t restart = 0, epoch = 0;  ///< epoch counts from 1
  double rel_error = 0;                ///< certified ||X - C S|| / ||X||
  double seconds = 0;                  ///< since the start of the run
};

struct NmfOptions {
  std::size_t k = 0;
  Init init = Init::nndsvd;
  std::uint64_t seed = 0;
  std::size_t restarts = 1;  ///< restart 0 uses `init`, restart r > 0 a random start with seed + r
  std::size_t max_epochs = 100;
  double tol = 1e-4;  ///< stop when an epoch lowers the error by less than tol (relative)
  Negatives negatives = Negatives::clip;
  /// With at least twice this many blocks, each restart first descends on a sample of about this many
  /// (every stride-th block) until it stalls (at most 100 epochs); 0: no warm-up.
  std::size_t warmup_blocks = 64;
  /// Blocks per wave: the basis is re-solved after every wave. Results depend on it, not on threads or ranks;
  /// a wave's blocks are what the threads of all ranks share, so use at least ranks x threads on clusters.
  std::size_t wave_blocks = 8;
  /// Written (atomically) after every epoch when not empty; removed by the caller once the basis is saved.
  std::filesystem::path checkpoint;
  bool resume = false;  ///< continue from `checkpoint` (which must exist and match the run)
  std::function<void(const EpochReport&)> on_epoch;
};

struct RestartResult {
  Eigen::MatrixXd basis;  ///< k x B, rows of unit L2 norm
  double rel_error = 0;
  std::size_t epochs = 0;
  bool converged = false;                        ///< stopped on tol (false: max_epochs reached)
  std::vector<double> history;                   ///< certified error after each epoch
  double mean_angle_deg = 0, max_angle_deg = 0;  ///< to the best restart's basis, components matched
};

struct NmfResult {
  std::vector<RestartResult> restarts;
  /// The best basis's own error: ||X - C* S|| / ||X|| with C* its exact NNLS coefficients, from a final
  /// certifying pass (at most the last epoch's error).
  double rel_error = 0;
  std::size_t best = 0;           ///< index of the restart with the lowest error
  Eigen::VectorXd weights;        ///< RMS coefficient of each component of the best basis
  std::uint64_t n = 0;            ///< spectra factored
  std::uint64_t negatives = 0;    ///< values below zero (clipped)
  std::uint64_t values = 0;       ///< n x bands
  Eigen::MatrixXd second_moment;  ///< uncentred X^T X / n (after clipping)
  double svd_bound = 0;           ///< the rank-k truncated-SVD error ||X - X_k|| / ||X||: no rank-k C S does better
  std::size_t passes = 0;         ///< passes over the data in this process (a resumed run counts its own)
  std::uint64_t nnls_unconverged = 0;  ///< coefficient solves that hit the iteration cap (expected 0)
  bool resumed = false;
  std::size_t warmup_epochs = 0;      ///< epochs on the warm-up sample (large data only; summed over restarts)
  std::size_t warmup_blocks = 0;      ///< blocks in that sample
  double warmup_pass_equivalent = 0;  ///< the warm-up's reading, in passes over the whole data
  const RestartResult& best_result() const { return restarts.at(best); }
};

/// Factors the selected spectra. Throws UsageError for bad options, InputError for non-finite data or
/// (with Negatives::reject) negative values, Interrupted (with what was kept) when a stop is requested.
/// Under several ranks every rank passes the same reader and options, streams its share of each wave and
/// gets the same result; only rank 0 writes the checkpoint.
NmfResult factorize(const store::BlockReader& reader, const NmfOptions& options,
                    const Collective& ranks = single_process());

/// Mean and largest angle in degrees between matched rows of two bases (rows matched to maximise the summed
/// cosine similarity: every permutation for k <= 8, greedily above).
std::pair<double, double> basis_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

}  // namespace specula::nmf
