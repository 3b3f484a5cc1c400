#pragma once
// The state of an NMF run after a finished epoch, saved so an interrupted run continues where it stopped.
// An HDF5 file (attribute specula_format = "nmf-checkpoint", format_version 1) written to a temporary name
// and renamed, so a checkpoint on disk is always complete.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace specula::nmf {

struct Checkpoint {
  std::string fingerprint;  ///< options and data identity; a resumed run must match it
  std::uint64_t n = 0, negatives = 0, values = 0;
  Eigen::MatrixXd gram;                     ///< X^T X (B x B) from the first pass
  std::size_t restart = 0, epoch = 0;       ///< the restart in progress and its finished epochs
  Eigen::MatrixXd basis;                    ///< that restart's current basis (k x B)
  std::vector<double> history;              ///< its errors so far
  Eigen::MatrixXd wave_ctc, wave_ctx;       ///< per wave (rows): C^T C and C^T X of its latest coefficients, flattened
  std::vector<double> wave_xx;              ///< per wave: ||X||^2
  std::vector<Eigen::MatrixXd> done_bases;  ///< finished restarts
  std::vector<std::vector<double>> done_histories;
  std::vector<int> done_converged;
};

/// Writes `c` to `path` atomically (temporary sibling, then rename).
void save_checkpoint(const std::filesystem::path& path, const Checkpoint& c);
/// Reads a checkpoint; throws InputError naming the file if it is missing, foreign, of another version or malformed.
Checkpoint load_checkpoint(const std::filesystem::path& path);

}  // namespace specula::nmf
