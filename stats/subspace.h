#pragma once
// Comparing learned bases (reference §7.3.1): principal angles between the spaces spanned by two sets of
// components (Björck & Golub 1973), and matching one basis's components to another's for plotting.
#include <Eigen/Core>
#include <vector>

namespace specula::stats {

/// Principal angles (radians, ascending) between the row spaces of A (k1 x B) and B (k2 x B); min(k1, k2) of them.
Eigen::VectorXd principal_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);
/// Row k-1 holds the principal angles in degrees between the first k rows of A and of B, for k = 1..k_max
/// (k_max <= min(k1, k2)).
std::vector<std::vector<double>> principal_angles_deg(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                                      std::size_t k_max);

/// B's components matched to A's: row i is the component of B most parallel to A's row i, signed so that
/// their dot product is non-negative; `order[i]` is its row in B and `sign[i]` the factor applied.
struct AlignedComponents {
  Eigen::MatrixXd components;
  std::vector<std::size_t> order;
  std::vector<int> sign;
};

/// Matches min(k1, k2) components of B to those of A, largest |cosine| first (each row of B used once).
AlignedComponents align_components(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

}  // namespace specula::stats
