#include "specula/core/eigenpairs.h"

#include <Spectra/MatOp/DenseSymMatProd.h>
#include <Spectra/SymEigsSolver.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <string>

#include "specula/core/error.h"

namespace specula {

void canonical_signs(Eigen::MatrixXd& v) {
  for (Eigen::Index c = 0; c < v.cols(); ++c) {
    Eigen::Index i = 0;
    v.col(c).cwiseAbs().maxCoeff(&i);
    if (v(i, c) < 0) v.col(c) = -v.col(c);
  }
}

Eigenpairs symmetric_eigenpairs(const Eigen::MatrixXd& m, std::size_t k) {
  const auto n = std::size_t(m.rows());
  if (m.rows() != m.cols()) throw UsageError("symmetric_eigenpairs: matrix is not square");
  if (k < 1 || k > n)
    throw UsageError("symmetric_eigenpairs: k = " + std::to_string(k) + " must be between 1 and " + std::to_string(n));
  Eigenpairs e;
  if (n <= 64 || 2 * k + 1 > n) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(m);
    if (solver.info() != Eigen::Success) e.converged = false;
    // Eigen sorts ascending; take the top k in descending order.
    e.values = solver.eigenvalues().reverse().head(Eigen::Index(k));
    e.vectors = solver.eigenvectors().rowwise().reverse().leftCols(Eigen::Index(k));
  } else {
    Spectra::DenseSymMatProd<double> op(m);
    const Eigen::Index ncv = Eigen::Index(std::min(n, std::max<std::size_t>(2 * k + 1, 20)));
    Spectra::SymEigsSolver<Spectra::DenseSymMatProd<double>> solver(op, Eigen::Index(k), ncv);
    solver.init();
    solver.compute(Spectra::SortRule::LargestAlge, 10000, 1e-13);
    e.converged = solver.info() == Spectra::CompInfo::Successful;
    e.values = solver.eigenvalues();
    e.vectors = solver.eigenvectors();
  }
  canonical_signs(e.vectors);
  return e;
}

}  // namespace specula
