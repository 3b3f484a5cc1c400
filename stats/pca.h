#pragma once
// Principal component analysis (reference §7.3): eigen-decomposition of the covariance, the basis it
// gives, and projection onto its first k components (eqs 7.2-7.3).
#include <Eigen/Core>

#include "specula/core/colour.h"
#include "specula/stats/moments.h"
#include "specula/store/basis.h"

namespace specula::stats {

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

/// A PCA basis from streamed moments: mean, all eigenvalues (descending) and explained variance ratios,
/// the first k components (k = 0: all), covariance and the uncentred second moment.
store::Basis pca_basis(const Moments& moments, const WavelengthGrid& wavelengths, std::size_t k = 0);

/// Coefficients of rows of spectra on the first k components: C = (X - mean) V_k^T (eq 7.2); out is n x k.
void pca_project(const store::Basis& basis, std::size_t k, const Eigen::Ref<const RowMatrixXd>& spectra,
                 Eigen::Ref<RowMatrixXd> coefficients);
/// Reconstruction from coefficients: X' = mean + C V_k (eq 7.3); out is n x B.
void pca_reconstruct(const store::Basis& basis, const Eigen::Ref<const RowMatrixXd>& coefficients,
                     Eigen::Ref<RowMatrixXd> spectra);

}  // namespace specula::stats
