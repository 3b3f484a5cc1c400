#pragma once
// Principal component analysis (reference §7.3): eigen-decomposition of the covariance, the basis it
// gives, and projection onto its first k components (eqs 7.2-7.3).
#include <Eigen/Core>

#include "specula/core/colour.h"
#include "specula/core/eigenpairs.h"
#include "specula/stats/moments.h"
#include "specula/store/basis.h"

namespace specula::stats {

/// The eigen-decomposition PCA uses is core's (specula/core/eigenpairs.h), shared with the codec's fitted bases.
using specula::canonical_signs;
using specula::Eigenpairs;
using specula::symmetric_eigenpairs;

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
