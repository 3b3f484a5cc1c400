#include "specula/stats/moments.h"

#include <gtest/gtest.h>

#include <random>

#include "specula/core/error.h"
#include "test_support.h"

using namespace specula;
using namespace specula::stats;

namespace {

RowMatrixXd random_spectra(Eigen::Index n, Eigen::Index b, double mean, double spread, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  // Correlated bands: a smooth random mixture so the covariance is far from diagonal.
  Eigen::MatrixXd mix(b, b);
  for (Eigen::Index i = 0; i < b; ++i)
    for (Eigen::Index j = 0; j < b; ++j) mix(i, j) = std::exp(-0.05 * double((i - j) * (i - j))) * (1.0 + 0.1 * g(rng));
  RowMatrixXd z(n, b);
  for (Eigen::Index i = 0; i < z.size(); ++i) z.data()[i] = g(rng);
  RowMatrixXd x = (z * mix.transpose()) * spread;
  x.array() += mean;
  return x;
}

// Two-pass reference in long double.
Eigen::MatrixXd two_pass_covariance(const RowMatrixXd& x) {
  const Eigen::Index n = x.rows(), b = x.cols();
  std::vector<long double> mu(std::size_t(b), 0.0L);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index k = 0; k < b; ++k) mu[std::size_t(k)] += x(i, k);
  for (auto& m : mu) m /= n;
  Eigen::MatrixXd c(b, b);
  for (Eigen::Index p = 0; p < b; ++p)
    for (Eigen::Index q = 0; q < b; ++q) {
      long double s = 0;
      for (Eigen::Index i = 0; i < n; ++i) s += (x(i, p) - mu[std::size_t(p)]) * (x(i, q) - mu[std::size_t(q)]);
      c(p, q) = double(s / (n - 1));
    }
  return c;
}

}  // namespace

TEST(Moments, LargeMeanTinySpreadExactWhereNaiveFormulaFails) {
  // Spectra of mean 1e4 and spread 1e-2: the covariance (~1e-4) is 1e-12 of E[x x^T] (~1e8).
  const RowMatrixXd x = random_spectra(20000, 8, 1e4, 1e-2, 7);
  const Eigen::MatrixXd ref = two_pass_covariance(x);
  Moments m(8);
  for (Eigen::Index r = 0; r < x.rows(); r += 1000) m.add(x.middleRows(r, std::min<Eigen::Index>(1000, x.rows() - r)));
  const double err = (m.covariance() - ref).norm() / ref.norm();
  EXPECT_LT(err, 1e-9);
  // The naive one-pass formula E[x x^T] - mu mu^T, accumulated in double, loses everything.
  Eigen::MatrixXd sxx = Eigen::MatrixXd::Zero(8, 8);
  Eigen::VectorXd sx = Eigen::VectorXd::Zero(8);
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    sxx += x.row(i).transpose() * x.row(i);
    sx += x.row(i).transpose();
  }
  const double n = double(x.rows());
  const Eigen::MatrixXd naive = (sxx - sx * sx.transpose() / n) / (n - 1);
  const double naive_err = (naive - ref).norm() / ref.norm();
  EXPECT_GT(naive_err, 1e-3) << "the naive formula was expected to fail here";
}

TEST(Moments, MergeEqualsOnePassOverTheUnion) {
  const RowMatrixXd x = random_spectra(3001, 5, 2.0, 0.5, 3);
  Moments whole(5), a(5), b(5);
  whole.add(x);
  a.add(x.topRows(1234));
  b.add(x.bottomRows(x.rows() - 1234));
  a.merge(b);
  EXPECT_EQ(a.count(), 3001u);
  EXPECT_LT((a.mean() - whole.mean()).norm(), 1e-13);
  EXPECT_LT((a.covariance() - whole.covariance()).norm() / whole.covariance().norm(), 1e-13);
  // Second moment identity: E[x x^T] computed directly.
  const Eigen::MatrixXd direct = x.transpose() * x / double(x.rows());
  EXPECT_LT((a.second_moment() - direct).norm() / direct.norm(), 1e-12);
  Moments empty(5);
  a.merge(empty);
  EXPECT_EQ(a.count(), 3001u);
  EXPECT_THROW(a.merge(Moments(4)), UsageError);
  EXPECT_THROW(Moments(5).covariance(), UsageError);
}

TEST(Moments, StreamedFromAStoreMatchesTwoPassAndIsIdenticalForAnyThreadCount) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  std::vector<double> rows;  // every valid spectrum, in store order
  {
    store::StoreWriter w(path, {});
    for (int i = 0; i < 3; ++i) {
      store::Cube c;
      c.resize(290 + 20 * std::size_t(i), 300, 12);  // 72-row chunks: several blocks per image
      const RowMatrixXd x = random_spectra(Eigen::Index(c.height * c.width), 12, 50.0, 3.0, unsigned(i + 1));
      for (std::size_t k = 0; k < c.data.size(); ++k) c.data[k] = float(x.data()[k]);
      c.mask.assign(c.height * c.width, 1);
      for (std::size_t p = 0; p < c.mask.size(); p += 3) c.mask[p] = 0;
      c.wavelengths = WavelengthGrid::range(400, 510, 10);
      w.add_image("img" + std::to_string(i), c);
      for (std::size_t p = 0; p < c.mask.size(); ++p)
        if (c.mask[p])
          for (std::size_t k = 0; k < 12; ++k) rows.push_back(double(c.data[p * 12 + k]));
    }
    w.commit();
  }
  const RowMatrixXd all = Eigen::Map<const RowMatrixXd>(rows.data(), Eigen::Index(rows.size() / 12), 12);
  store::Store s = store::Store::open(path);
  store::BlockReader reader(s, {}, 500);
  ASSERT_GT(reader.block_count(), 10u);
  omp_set_num_threads(1);
  const Moments one = stream_moments(reader);
  omp_set_num_threads(2);
  const Moments two = stream_moments(reader);
  EXPECT_EQ(one.count(), std::uint64_t(all.rows()));
  EXPECT_TRUE(one.scatter() == two.scatter()) << "results depend on the thread count";
  EXPECT_TRUE(one.mean() == two.mean());
  const Eigen::MatrixXd ref = two_pass_covariance(all);
  ASSERT_TRUE(ref.allFinite());
  ASSERT_TRUE(one.covariance().allFinite());
  EXPECT_LT((one.covariance() - ref).norm() / ref.norm(), 1e-12);
}
