#include "specula/stats/pca.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <random>

#include "specula/core/error.h"

using namespace specula;
using namespace specula::stats;

namespace {

// A symmetric positive semi-definite matrix with known, well separated eigenvalues.
Eigen::MatrixXd known_spectrum_matrix(Eigen::Index n, Eigen::VectorXd& values, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = g(rng);
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::MatrixXd q = qr.householderQ();
  values.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) values[i] = std::pow(0.7, double(i)) * 10.0;
  return q * values.asDiagonal() * q.transpose();
}

}  // namespace

TEST(Eigenpairs, DenseAndLanczosAgreeOnA198BandMatrix) {
  Eigen::VectorXd values;
  const Eigen::MatrixXd m = known_spectrum_matrix(198, values, 5);
  const Eigenpairs lanczos = symmetric_eigenpairs(m, 8);  // 198 bands, k = 8: Spectra's SymEigsSolver
  const Eigenpairs dense = symmetric_eigenpairs(m, 198);
  ASSERT_TRUE(lanczos.converged);
  for (Eigen::Index i = 0; i < 8; ++i) {
    EXPECT_NEAR(lanczos.values[i], values[i], 1e-10 * values[0]);
    EXPECT_NEAR(dense.values[i], values[i], 1e-10 * values[0]);
    // Same vectors with the same deterministic sign.
    EXPECT_LT((lanczos.vectors.col(i) - dense.vectors.col(i)).norm(), 1e-8) << i;
    Eigen::Index arg = 0;
    lanczos.vectors.col(i).cwiseAbs().maxCoeff(&arg);
    EXPECT_GT(lanczos.vectors(arg, i), 0);
    EXPECT_LT((m * lanczos.vectors.col(i) - values[i] * lanczos.vectors.col(i)).norm(), 1e-9 * values[0]);
  }
  EXPECT_THROW(symmetric_eigenpairs(m, 0), UsageError);
  EXPECT_THROW(symmetric_eigenpairs(m, 199), UsageError);
}

TEST(Pca, BasisOfDataInAKnownPlaneAndExactReconstruction) {
  // Spectra mean + a u + b v with orthonormal u, v: two non-zero eigenvalues, reconstruction exact at k = 2.
  const Eigen::Index bands = 31, n = 5000;
  Eigen::VectorXd u(bands), v(bands), mean(bands);
  for (Eigen::Index i = 0; i < bands; ++i) {
    u[i] = std::sin(0.1 * double(i));
    v[i] = std::cos(0.23 * double(i));
    mean[i] = 0.3 + 0.01 * double(i);
  }
  u.normalize();
  v -= v.dot(u) * u;
  v.normalize();
  std::mt19937_64 rng(2);
  std::normal_distribution<double> g;
  RowMatrixXd x(n, bands);
  for (Eigen::Index r = 0; r < n; ++r) x.row(r) = (mean + 2.0 * g(rng) * u + 0.5 * g(rng) * v).transpose();
  Moments m(bands);
  m.add(x);
  const store::Basis basis = pca_basis(m, WavelengthGrid::range(420, 720, 10), 4);
  ASSERT_EQ(basis.k(), 4u);
  EXPECT_NEAR(basis.explained_variance_ratio.head(2).sum(), 1.0, 1e-12);
  EXPECT_NEAR(basis.explained_variance_ratio.sum(), 1.0, 1e-12);
  // The first two components span the plane of u and v (their in-plane orientation depends on the sample).
  for (Eigen::Index c = 0; c < 2; ++c) {
    const Eigen::VectorXd comp = basis.components.row(c).transpose();
    EXPECT_NEAR(std::hypot(comp.dot(u), comp.dot(v)), 1.0, 1e-9) << c;
  }
  RowMatrixXd c(n, 2), back(n, bands);
  pca_project(basis, 2, x, c);
  pca_reconstruct(basis, c, back);
  EXPECT_LT((back - x).cwiseAbs().maxCoeff(), 1e-10);
  RowMatrixXd c1(n, 1), back1(n, bands);
  pca_project(basis, 1, x, c1);
  pca_reconstruct(basis, c1, back1);
  // The residual of k = 1 is exactly the v component: its mean square is the second eigenvalue.
  EXPECT_NEAR((back1 - x).squaredNorm() / double(n - 1), basis.eigenvalues[1], 1e-9 * basis.eigenvalues[1]);
  EXPECT_THROW(pca_project(basis, 5, x, c), UsageError);
}
