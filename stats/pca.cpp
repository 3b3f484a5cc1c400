#include "specula/stats/pca.h"

#include <Eigen/Eigenvalues>

#include "specula/core/error.h"

namespace specula::stats {

store::Basis pca_basis(const Moments& moments, const WavelengthGrid& wavelengths, std::size_t k) {
  const std::size_t b = moments.bands();
  if (wavelengths.size() != b)
    throw UsageError("pca_basis: " + std::to_string(wavelengths.size()) + " wavelengths for " + std::to_string(b) +
                     " bands");
  if (k == 0) k = b;
  const Eigen::MatrixXd cov = moments.covariance();
  store::Basis basis;
  basis.method = "pca";
  basis.wavelengths = wavelengths;
  basis.n = moments.count();
  basis.mean = moments.mean();
  basis.covariance = cov;
  basis.second_moment = moments.second_moment();
  // Every eigenvalue (cheap for any realistic band count); components for the first k.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> values(cov, Eigen::EigenvaluesOnly);
  basis.eigenvalues = values.eigenvalues().reverse();
  const double total = basis.eigenvalues.sum();
  basis.explained_variance_ratio =
      total > 0 ? Eigen::VectorXd(basis.eigenvalues / total) : Eigen::VectorXd::Zero(Eigen::Index(b));
  const Eigenpairs top = symmetric_eigenpairs(cov, k);
  if (!top.converged) throw Error("PCA: the eigensolver did not converge for k = " + std::to_string(k));
  basis.components = top.vectors.transpose();
  return basis;
}

void pca_project(const store::Basis& basis, std::size_t k, const Eigen::Ref<const RowMatrixXd>& spectra,
                 Eigen::Ref<RowMatrixXd> coefficients) {
  if (k < 1 || k > basis.k())
    throw UsageError("pca_project: k = " + std::to_string(k) + ": the basis has " + std::to_string(basis.k()) +
                     " components; give k between 1 and " + std::to_string(basis.k()));
  if (spectra.cols() != basis.components.cols() || coefficients.rows() != spectra.rows() ||
      coefficients.cols() != Eigen::Index(k))
    throw UsageError("pca_project: spectra, basis and output sizes disagree");
  coefficients.noalias() =
      (spectra.rowwise() - basis.mean.transpose()) * basis.components.topRows(Eigen::Index(k)).transpose();
}

void pca_reconstruct(const store::Basis& basis, const Eigen::Ref<const RowMatrixXd>& coefficients,
                     Eigen::Ref<RowMatrixXd> spectra) {
  const Eigen::Index k = coefficients.cols();
  if (k < 1 || k > Eigen::Index(basis.k()) || spectra.rows() != coefficients.rows() ||
      spectra.cols() != basis.components.cols())
    throw UsageError("pca_reconstruct: coefficients, basis and output sizes disagree");
  spectra.noalias() = coefficients * basis.components.topRows(k);
  spectra.rowwise() += basis.mean.transpose();
}

}  // namespace specula::stats
