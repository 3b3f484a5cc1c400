// The projector against independent answers: PCA coefficients from the formula (x - mean) V_k^T evaluated here,
// exact reconstruction inside the span, NMF coefficients from brute-force NNLS over every passive set, errors from
// their definition, misuse named by parameter, and identical results on 1 and 2 threads.
#include "specula/stats/project.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/QR>
#include <cmath>
#include <random>
#include <string>

#include "specula/core/error.h"
#include "specula/core/nnls.h"
#include "specula/core/parallel.h"
#include "test_support.h"

using namespace specula;
using namespace specula::stats;

namespace {

constexpr Eigen::Index kB = 12;

RowMatrixXd random_rows(Eigen::Index n, std::uint64_t seed, double lo = -1, double hi = 1) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  RowMatrixXd x(n, kB);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] = u(rng);
  return x;
}

// A PCA basis: orthonormal rows from a QR of random data, and a mean.
store::Basis pca_basis_of(Eigen::Index k) {
  store::Basis b;
  b.method = "pca";
  b.wavelengths = WavelengthGrid::range(400, 400 + 10 * double(kB - 1), 10);
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(random_rows(kB, 3)).householderQ();
  b.components = q.leftCols(k).transpose();
  b.mean = random_rows(1, 4, 0, 1).row(0).transpose();
  return b;
}

store::Basis nmf_basis_of(Eigen::Index k) {
  store::Basis b;
  b.method = "nmf";
  b.wavelengths = WavelengthGrid::range(400, 400 + 10 * double(kB - 1), 10);
  b.components = random_rows(k, 5, 0, 1);
  return b;
}

}  // namespace

TEST(Projector, PcaCoefficientsAreTheCentredProductWithTheFirstKComponents) {
  const store::Basis b = pca_basis_of(kB);
  const RowMatrixXd x = random_rows(40, 7);
  for (long long k : {1LL, 3LL, 12LL}) {
    const Projector p(b, k, "pca");
    EXPECT_EQ(p.k(), std::size_t(k));
    RowMatrixXd c(40, k);
    p.project(x, c);
    for (Eigen::Index r = 0; r < x.rows(); ++r)
      for (Eigen::Index j = 0; j < k; ++j) {
        double want = 0;
        for (Eigen::Index i = 0; i < kB; ++i) want += (x(r, i) - b.mean[i]) * b.components(j, i);
        EXPECT_NEAR(c(r, j), want, 1e-12) << r << "," << j;
      }
  }
  EXPECT_EQ(Projector(b, std::nullopt).k(), std::size_t(kB));  // no k: all components
}

TEST(Projector, ReconstructionInsideTheSpanIsExact) {
  const store::Basis b = pca_basis_of(4);
  const Projector p(b, 3, "pca");
  // x = mean + a V_3: inside the span of the first 3 components about the mean.
  const RowMatrixXd a = random_rows(20, 8).leftCols(3);
  RowMatrixXd x = a * b.components.topRows(3);
  x.rowwise() += b.mean.transpose();
  RowMatrixXd c(20, 3), back(20, kB);
  p.project(x, c);
  p.reconstruct(c, back);
  EXPECT_LT((c - a).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((back - x).cwiseAbs().maxCoeff(), 1e-12);

  const store::Basis n = nmf_basis_of(3);
  const Projector q(n, std::nullopt, "nmf");
  const RowMatrixXd w = random_rows(20, 9, 0.1, 2).leftCols(3);  // positive weights: NNLS is unconstrained there
  const RowMatrixXd y = w * n.components;
  RowMatrixXd cw(20, 3), yb(20, kB);
  q.project(y, cw);
  q.reconstruct(cw, yb);
  EXPECT_LT((cw - w).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((yb - y).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Projector, NmfCoefficientsAreBruteForceNnls) {
  for (Eigen::Index k : {2, 4, 11}) {  // 11: beyond GramNnls's cached passive sets
    const store::Basis b = nmf_basis_of(k);
    const Projector p(b, std::nullopt, "nmf");
    const RowMatrixXd x = random_rows(60, 10 + std::uint64_t(k), -0.3, 1);
    RowMatrixXd c(60, k);
    p.project(x, c);
    const Eigen::MatrixXd gram = b.components * b.components.transpose();
    int binding = 0;
    for (Eigen::Index r = 0; r < x.rows(); ++r) {
      const Eigen::VectorXd ref = nnls_brute_force(gram, b.components * x.row(r).transpose());
      EXPECT_LE((c.row(r).transpose() - ref).norm(), 1e-9 * std::max(1.0, ref.norm())) << "k=" << k << " row " << r;
      binding += (ref.array() == 0).any();
    }
    EXPECT_GT(binding, 5) << "k=" << k << ": no constraint binds";
  }
}

TEST(Projector, ErrorsFollowTheirDefinition) {
  const store::Basis b = pca_basis_of(kB);
  const Projector p(b, 2);
  const RowMatrixXd x = random_rows(30, 11);
  RowMatrixXd c(30, 2), xr(30, kB);
  p.project(x, c);
  p.reconstruct(c, xr);
  Eigen::VectorXd sq(30);
  squared_errors(x, xr, sq);
  ProjectionError all, first, second;
  double sum = 0, worst = 0;
  for (Eigen::Index i = 0; i < 30; ++i) {
    double e2 = 0;
    for (Eigen::Index j = 0; j < kB; ++j) e2 += (x(i, j) - xr(i, j)) * (x(i, j) - xr(i, j));
    EXPECT_NEAR(sq[i], e2, 1e-12);
    sum += e2;
    worst = std::max(worst, std::sqrt(e2));
    all.add(sq[i]);
    (i < 10 ? first : second).add(sq[i]);
  }
  first.merge(second);
  EXPECT_EQ(all.count, 30u);
  EXPECT_NEAR(all.rms(kB), std::sqrt(sum / (30.0 * double(kB))), 1e-14);
  EXPECT_NEAR(all.max_error, worst, 1e-14);
  EXPECT_EQ(first.count, all.count);
  EXPECT_NEAR(first.rms(kB), all.rms(kB), 1e-14);
  EXPECT_EQ(first.max_error, all.max_error);
  EXPECT_TRUE(std::isnan(ProjectionError{}.rms(kB)));
}

TEST(Projector, MisuseIsNamedByParameter) {
  const store::Basis pca = pca_basis_of(5), nmf = nmf_basis_of(3);
  for (long long k : {0LL, -1LL, 6LL}) {
    EXPECT_THROW(Projector(pca, k, "b"), UsageError);
    const std::string m = test::error_of<std::exception>([&] { Projector(pca, k, "b"); });
    EXPECT_NE(m.find("k = " + std::to_string(k)), std::string::npos) << m;
    EXPECT_NE(m.find("give k between 1 and 5"), std::string::npos) << m;
    EXPECT_EQ(m.find("-k"), std::string::npos) << m;
  }
  EXPECT_THROW(Projector(nmf, 2, "n"), UsageError);
  EXPECT_NE(test::error_of<std::exception>([&] {
              Projector(nmf, 2, "n");
            }).find("k = 2: NMF basis n has 3 components and projects onto all"),
            std::string::npos);
  EXPECT_NO_THROW(Projector(nmf, 3, "n"));

  store::Basis odd = nmf;
  odd.method = "ica";
  EXPECT_THROW(Projector(odd, std::nullopt, "odd"), InputError);
  EXPECT_NE(test::error_of<std::exception>([&] { basis_method(odd, "odd"); }).find("basis odd has method 'ica'"),
            std::string::npos);
  store::Basis meanless = pca;
  meanless.mean.resize(0);
  EXPECT_THROW(basis_method(meanless, "m"), InputError);
  EXPECT_NE(test::error_of<std::exception>([&] {
              Projector(meanless, 2, "m");
            }).find("basis m is a pca basis without a mean"),
            std::string::npos);

  const Projector p(pca, 2, "b");
  RowMatrixXd x(4, kB), wrong(4, kB - 1), c(4, 2), c3(4, 3);
  x.setZero();
  EXPECT_THROW(p.project(wrong, c), UsageError);
  EXPECT_THROW(p.project(x, c3), UsageError);
  EXPECT_THROW(p.reconstruct(c3, x), UsageError);
  EXPECT_NO_THROW(p.check_wavelengths(pca.wavelengths, "image a"));
  EXPECT_THROW(p.check_wavelengths(WavelengthGrid::range(400, 700, 10), "image a"), InputError);
  const std::string m = test::error_of<std::exception>(
      [&] { p.check_wavelengths(WavelengthGrid::range(400, 700, 10), "image a", "resample it"); });
  EXPECT_NE(m.find("image a has"), std::string::npos) << m;
  EXPECT_NE(m.find("; resample it"), std::string::npos) << m;
}

// Blocks projected concurrently on one shared projector: the same bits on 1 and 2 threads, and the same as one call.
TEST(Projector, OneAndTwoThreadsGiveIdenticalResults) {
  const store::Basis pca = pca_basis_of(kB), nmf = nmf_basis_of(4);
  const RowMatrixXd x = random_rows(4000, 12, -0.2, 1);
  for (const Projector& p : {Projector(pca, 5), Projector(nmf, std::nullopt)}) {
    const auto k = Eigen::Index(p.k());
    constexpr Eigen::Index kRows = 100;
    auto run = [&](int threads) {
      RowMatrixXd c(x.rows(), k), xr(x.rows(), kB);
      const int before = omp_get_max_threads();
      omp_set_num_threads(threads);
      parallel_for(std::size_t(x.rows() / kRows), [&](std::size_t i) {
        const Eigen::Index r = Eigen::Index(i) * kRows;
        p.project(x.middleRows(r, kRows), c.middleRows(r, kRows));
        p.reconstruct(c.middleRows(r, kRows), xr.middleRows(r, kRows));
      });
      omp_set_num_threads(before);
      return std::pair{c, xr};
    };
    const auto one = run(1), two = run(2);
    EXPECT_TRUE(one.first == two.first);
    EXPECT_TRUE(one.second == two.second);
    RowMatrixXd c(x.rows(), k);
    p.project(x, c);
    EXPECT_LT((c - one.first).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(Projector, ProjectRowsReturnsEveryOutputAndSumsOnlyTheKeptRows) {
  const stats::Projector p(nmf_basis_of(4), std::nullopt);
  const RowMatrixXd x = random_rows(9, 21, 0, 1);
  const std::vector<std::uint8_t> mask{1, 0, 1, 1, 0, 1, 1, 1, 0};
  RowMatrixXd c(9, 4), xr(9, kB);
  Eigen::VectorXd e(9);
  const stats::ProjectionError s = stats::project_rows(p, x, mask, c, xr, e);
  RowMatrixXd c_ref(9, 4), xr_ref(9, kB);
  p.project(x, c_ref);
  p.reconstruct(c_ref, xr_ref);
  EXPECT_EQ(c, c_ref);
  EXPECT_EQ(xr, xr_ref);
  double sum_sq = 0, max_error = 0;
  for (Eigen::Index i = 0; i < 9; ++i) {
    const double direct = (x.row(i) - xr_ref.row(i)).norm();
    EXPECT_NEAR(e[i], direct, 1e-12) << i;
    if (!mask[std::size_t(i)]) continue;
    sum_sq += direct * direct;
    max_error = std::max(max_error, direct);
  }
  EXPECT_EQ(s.count, 6u);
  EXPECT_NEAR(s.sum_sq, sum_sq, 1e-12);
  EXPECT_NEAR(s.max_error, max_error, 1e-12);
  EXPECT_THROW(stats::project_rows(p, x, std::vector<std::uint8_t>(8, 1), c, xr, e), UsageError);
}
