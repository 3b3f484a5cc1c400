#pragma once
// The processes of one run (MPI ranks, or just this process) and the one collective the algorithms need:
// every rank's partial result gathered in rank order, so sums are formed in a fixed order on every rank.
// The interface lives here so the libraries stay free of MPI; apps/ provides the MPI implementation.
#include <span>
#include <vector>

namespace specula {

class Collective {
 public:
  virtual ~Collective() = default;
  /// This process's rank in [0, size()).
  virtual int rank() const = 0;
  /// Number of processes sharing the work.
  virtual int size() const = 0;
  /// Concatenates every rank's `mine` (the same length on all ranks) in rank order into `all`
  /// (size() * mine.size() values) on every rank.
  virtual void allgather(std::span<const double> mine, std::span<double> all) const = 0;
};

/// The run of one process: rank 0 of 1, allgather copies.
const Collective& single_process();

/// Sums `values` element-wise over the ranks, adding rank 0's, then rank 1's, ..., so every rank gets the
/// same bits whatever the process layout.
void sum_in_rank_order(const Collective& c, std::span<double> values);

/// Blocks [first, last) of n split in contiguous shares, one per rank: this rank's share.
struct Share {
  std::size_t first = 0, last = 0;
};
Share share_of(const Collective& c, std::size_t n);

}  // namespace specula
