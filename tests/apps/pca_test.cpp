// `specula pca` end to end: JSON contract, the basis saved with provenance, agreement with an independent
// two-pass answer, and bad selections.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

TEST(PcaCli, EigenvaluesMatchATwoPassAnswerAndTheBasisIsSaved) {
  test::ScratchDir dir;
  auto db = dir / "db.h5";
  ASSERT_EQ(run_specula("-q synth-db -o '" + db.string() + "' --images 3 --size 60x90 --seed 4").status, 0);
  auto r = run_specula("-q pca '" + db.string() + "' --name p --json");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"\"n\":", "\"bands\":31", "\"wavelengths\":", "\"mean\":", "\"eigenvalues\":",
                          "\"explained_variance_ratio\":", "\"seconds\":"})
    EXPECT_NE(r.output.find(key), std::string::npos) << key;
  // Independent answer: every valid spectrum read whole, two-pass covariance, dense eigenvalues.
  auto s = store::Store::open(db);
  std::vector<double> rows;
  for (const auto& name : s.images()) {
    auto c = s.read_image(name);
    for (std::size_t p = 0; p < c.height * c.width; ++p)
      if (c.mask[p])
        for (std::size_t k = 0; k < 31; ++k) rows.push_back(c.data[p * 31 + k]);
  }
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 31, Eigen::RowMajor>> x(
      rows.data(), Eigen::Index(rows.size() / 31), 31);
  const Eigen::RowVectorXd mean = x.colwise().mean();
  const Eigen::MatrixXd centred = x.rowwise() - mean;
  const Eigen::MatrixXd cov = centred.transpose() * centred / double(x.rows() - 1);
  const Eigen::VectorXd ref = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(cov).eigenvalues().reverse();
  const store::Basis b = s.read_basis("p");
  EXPECT_EQ(b.method, "pca");
  EXPECT_EQ(b.n, std::uint64_t(x.rows()));
  EXPECT_NE(r.output.find("\"n\":" + std::to_string(x.rows())), std::string::npos);
  for (Eigen::Index i = 0; i < 31; ++i) {
    if (ref[i] > 1e-12 * ref[0]) {
      EXPECT_NEAR(b.eigenvalues[i], ref[i], 1e-9 * ref[0]) << i;
    }
  }
  const Eigen::VectorXd mean_col = mean.transpose();
  const Eigen::VectorXd mean_diff = b.mean - mean_col;
  EXPECT_LT(mean_diff.norm(), 1e-12 * mean_col.norm());
  EXPECT_NE(b.provenance.command_line.find("pca"), std::string::npos);
  // Components are orthonormal rows.
  EXPECT_LT((b.components * b.components.transpose() - Eigen::MatrixXd::Identity(31, 31)).norm(), 1e-10);
}

TEST(PcaCli, BadSelectionsAreOneLineAndLeaveTheStore) {
  test::ScratchDir dir;
  auto db = dir / "db.h5";
  ASSERT_EQ(run_specula("-q synth-db -o '" + db.string() + "' --images 1 --size 10x10").status, 0);
  const std::string before = test::read_bytes(db);
  for (const char* args : {"--images 'nothing*'", "--collection none", "-k 40"}) {
    auto r = run_specula("-q pca '" + db.string() + "' " + args);
    EXPECT_EQ(r.status, 1) << args << ": " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << ": " << r.output;
  }
  EXPECT_EQ(test::read_bytes(db), before);
  ASSERT_EQ(run_specula("-q pca '" + db.string() + "'").status, 0);
  auto again = run_specula("-q pca '" + db.string() + "'");
  EXPECT_EQ(again.status, 1);
  EXPECT_NE(again.output.find("basis 'pca' exists already"), std::string::npos) << again.output;
}
