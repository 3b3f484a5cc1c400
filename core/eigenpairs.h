#pragma once
// The top eigenpairs of a symmetric matrix with a deterministic sign: what PCA (stats/pca.h) and the codec's
// fitted spectral bases (codec/spc.h) both need.
#include <Eigen/Core>
#include <cstddef>

namespace specula {

/// Eigenpairs of a symmetric matrix, eigenvalues descending; each eigenvector's largest-magnitude entry is
/// positive (a deterministic sign).
struct Eigenpairs {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;  ///< one eigenvector per column
  bool converged = true;    ///< false if the iterative solver stopped early (values are then approximate)
};

/// The top k eigenpairs of symmetric `m`: dense (Eigen) when k is large relative to the size or the size is
/// small (<= 64), else Lanczos (Spectra's SymEigsSolver). Throws UsageError unless 1 <= k <= size.
Eigenpairs symmetric_eigenpairs(const Eigen::MatrixXd& m, std::size_t k);
/// Forces the sign convention (largest-magnitude entry positive) on the columns of v.
void canonical_signs(Eigen::MatrixXd& v);

}  // namespace specula
