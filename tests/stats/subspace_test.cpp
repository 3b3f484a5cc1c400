// Principal angles against closed forms, and matching one basis's components to another's.
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <numbers>
#include <random>

#include "specula/core/error.h"
#include "specula/stats/subspace.h"

using namespace specula;

namespace {

constexpr double kPi = std::numbers::pi;

Eigen::MatrixXd random_matrix(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Eigen::MatrixXd m(rows, cols);
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = g(rng);
  return m;
}

// An orthonormal B x B matrix, so its rows are orthonormal directions in R^B.
Eigen::MatrixXd random_rotation(Eigen::Index bands, unsigned seed) {
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(random_matrix(bands, bands, seed));
  return qr.householderQ() * Eigen::MatrixXd::Identity(bands, bands);
}

}  // namespace

TEST(Subspace, IdenticalSpacesHaveZeroAngles) {
  const Eigen::MatrixXd a = random_matrix(4, 31, 1);
  const Eigen::VectorXd angles = stats::principal_angles(a, a);
  ASSERT_EQ(angles.size(), 4);
  for (Eigen::Index i = 0; i < 4; ++i) EXPECT_NEAR(angles[i], 0.0, 1e-12);
}

TEST(Subspace, PlaneRotatedOutOfItself) {
  // span{e1, e2} against span{e1, cos t e2 + sin t e3}: angles {0, t}, in any orientation of R^B.
  const Eigen::MatrixXd r = random_rotation(10, 2);
  for (double t : {1e-9, 1e-6, 0.01, 0.3, kPi / 4, 1.2, kPi / 2}) {
    Eigen::MatrixXd a(2, 10), b(2, 10);
    a << r.row(0), r.row(1);
    b << r.row(0), std::cos(t) * r.row(1) + std::sin(t) * r.row(2);
    const Eigen::VectorXd angles = stats::principal_angles(a, b);
    ASSERT_EQ(angles.size(), 2);
    EXPECT_NEAR(angles[0], 0.0, 1e-12) << "t " << t;
    EXPECT_NEAR(angles[1], t, 1e-12 + 1e-9 * t) << "t " << t;
  }
}

TEST(Subspace, AnglesInDegreesPerLeadingK) {
  // First rows equal, second rows 30 degrees apart, third rows orthogonal to everything else: k = 1 gives {0},
  // k = 2 {0, 30}, k = 3 {0, 30, 90}.
  const Eigen::MatrixXd r = random_rotation(8, 3);
  Eigen::MatrixXd a(3, 8), b(3, 8);
  const double t = kPi / 6;
  a << r.row(0), r.row(1), r.row(3);
  b << r.row(0), std::cos(t) * r.row(1) + std::sin(t) * r.row(2), r.row(4);
  const auto deg = stats::principal_angles_deg(a, b, 3);
  ASSERT_EQ(deg.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) ASSERT_EQ(deg[k].size(), k + 1);
  EXPECT_NEAR(deg[0][0], 0, 1e-9);
  EXPECT_NEAR(deg[1][1], 30, 1e-9);
  EXPECT_NEAR(deg[2][2], 90, 1e-9);
}

TEST(Subspace, OrthogonalSpacesAreAtNinetyDegrees) {
  const Eigen::MatrixXd r = random_rotation(12, 3);
  const Eigen::VectorXd angles = stats::principal_angles(r.topRows(3), r.middleRows(3, 5));
  ASSERT_EQ(angles.size(), 3);
  for (Eigen::Index i = 0; i < 3; ++i) EXPECT_NEAR(angles[i], kPi / 2, 1e-12);
}

TEST(Subspace, AnglesDependOnlyOnTheSpaces) {
  // Scaling and mixing the rows within each space (an invertible k x k map) leaves the angles alone.
  const Eigen::MatrixXd a = random_matrix(3, 31, 4), b = random_matrix(5, 31, 5);
  const Eigen::VectorXd reference = stats::principal_angles(a, b);
  Eigen::MatrixXd mix_a = random_matrix(3, 3, 6), mix_b = random_matrix(5, 5, 7);
  mix_a.row(0) *= 1e3;
  mix_b.row(4) *= 1e-3;
  const Eigen::VectorXd mixed = stats::principal_angles(mix_a * a, mix_b * b);
  ASSERT_EQ(mixed.size(), 3);
  for (Eigen::Index i = 0; i < 3; ++i) EXPECT_NEAR(mixed[i], reference[i], 1e-9);
  const Eigen::VectorXd swapped = stats::principal_angles(b, a);
  for (Eigen::Index i = 0; i < 3; ++i) EXPECT_NEAR(swapped[i], reference[i], 1e-12);
  for (Eigen::Index i = 1; i < 3; ++i) EXPECT_LE(reference[i - 1], reference[i]);
}

TEST(Subspace, DependentRowsSpanTheirRank) {
  Eigen::MatrixXd a = random_matrix(3, 8, 8);
  a.row(2) = 2 * a.row(0) - a.row(1);
  EXPECT_EQ(stats::principal_angles(a, a).size(), 2);
}

TEST(Subspace, MismatchedBandsAreRejected) {
  EXPECT_THROW(stats::principal_angles(random_matrix(2, 31, 9), random_matrix(2, 30, 10)), UsageError);
  EXPECT_THROW(stats::principal_angles(Eigen::MatrixXd(0, 31), random_matrix(2, 31, 10)), UsageError);
}

TEST(Subspace, AlignmentRecoversOrderAndSigns) {
  const Eigen::MatrixXd a = random_rotation(16, 11).topRows(4);
  Eigen::MatrixXd b(5, 16);
  b << -a.row(2), a.row(0), random_rotation(16, 12).row(0) * 1e-3, -3 * a.row(3), a.row(1) + 0.05 * a.row(0);
  const stats::AlignedComponents aligned = stats::align_components(a, b);
  ASSERT_EQ(aligned.components.rows(), 4);
  EXPECT_EQ(aligned.order, (std::vector<std::size_t>{1, 4, 0, 3}));
  EXPECT_EQ(aligned.sign, (std::vector<int>{1, 1, -1, -1}));
  for (Eigen::Index i = 0; i < 4; ++i) {
    EXPECT_GT(aligned.components.row(i).dot(a.row(i)), 0);
    EXPECT_TRUE(aligned.components.row(i).isApprox(aligned.sign[std::size_t(i)] *
                                                   b.row(Eigen::Index(aligned.order[std::size_t(i)]))));
  }
}

TEST(Subspace, AlignmentOfABasisWithItselfIsTheIdentity) {
  const Eigen::MatrixXd a = random_matrix(6, 31, 13);
  const stats::AlignedComponents aligned = stats::align_components(a, -a);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(aligned.order[i], i);
    EXPECT_EQ(aligned.sign[i], -1);
  }
  EXPECT_TRUE(aligned.components.isApprox(a));
}
