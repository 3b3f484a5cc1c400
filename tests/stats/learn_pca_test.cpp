// learn_pca on a small collection against a brute-force mean and covariance eigen-decomposition.
#include "specula/stats/learn_pca.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

#include "specula/core/error.h"
#include "specula/store/learned_basis.h"
#include "test_support.h"

using namespace specula;

namespace {
store::Collection random_collection(std::size_t n, std::size_t bands, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  store::Collection c;
  c.wavelengths = WavelengthGrid::range(400, 400 + 10 * double(bands - 1), 10);
  for (std::size_t i = 0; i < n; ++i) c.names.push_back("s" + std::to_string(i));
  c.values.resize(n * bands);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t b = 0; b < bands; ++b) c.values[i * bands + b] = u(rng) * float(b + 1);  // distinct variances
  c.units = "reflectance";
  return c;
}
}  // namespace

TEST(LearnPca, MeanEigenvaluesAndProvenance) {
  test::ScratchDir dir;
  const auto path = dir / "db.h5";
  const store::Collection c = random_collection(200, 4, 7);
  {
    store::StoreWriter w(path, {});
    w.add_collection("c", c);
    w.add_collection("one", random_collection(1, 4, 8));
    w.commit();
  }
  std::vector<store::Store> stores;
  stores.push_back(store::Store::open(path));
  const stats::LearnedPca r = stats::learn_pca(stores, {.collection = "c"}, 2);
  Eigen::MatrixXd x(200, 4);
  for (Eigen::Index i = 0; i < 200; ++i)
    for (Eigen::Index b = 0; b < 4; ++b) x(i, b) = c.values[std::size_t(i * 4 + b)];
  const Eigen::VectorXd mean = x.colwise().mean();
  const Eigen::MatrixXd centred = x.rowwise() - mean.transpose();
  const Eigen::MatrixXd cov = centred.transpose() * centred / 199.0;  // the sample covariance (n - 1)
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
  ASSERT_EQ(r.basis.eigenvalues.size(), 4);
  for (Eigen::Index b = 0; b < 4; ++b) EXPECT_NEAR(r.basis.mean[b], mean[b], 1e-6);
  for (Eigen::Index i = 0; i < 4; ++i)
    EXPECT_NEAR(r.basis.eigenvalues[i], es.eigenvalues()[3 - i], 1e-6 * es.eigenvalues()[3]);
  EXPECT_EQ(r.basis.k(), 2u);
  EXPECT_EQ(r.basis.n, 200u);
  EXPECT_EQ(r.basis.source, "collection c");
  EXPECT_EQ(r.basis.provenance.source_file, path.string());
  EXPECT_EQ(r.basis.provenance.importer, "pca");
  EXPECT_THROW(stats::learn_pca(stores, {.collection = "c"}, 5), UsageError);
  EXPECT_THROW(stats::learn_pca(stores, {.collection = "one"}, 0), InputError);

  EXPECT_FALSE(store::holds_basis(path, "pca"));
  store::save_basis(path, "pca", r.basis, false, "test");
  EXPECT_TRUE(store::holds_basis(path, "pca"));
  EXPECT_FALSE(store::holds_basis(dir / "absent.h5", "pca"));
  EXPECT_EQ(store::Store::open(path).read_basis("pca").source, "collection c");
}
