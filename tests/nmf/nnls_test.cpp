#include "specula/nmf/nnls.h"

#include <gtest/gtest.h>

#include <random>

#include "specula/core/error.h"

using namespace specula;
using namespace specula::nmf;

namespace {

// A random NNLS problem min ||S^T c - x|| in Gram form, with x of mixed signs so some constraints bind.
void random_problem(int k, int b, std::mt19937_64& rng, Eigen::MatrixXd& gram, Eigen::VectorXd& h) {
  std::normal_distribution<double> g;
  Eigen::MatrixXd s(k, b);
  for (Eigen::Index i = 0; i < s.size(); ++i) s.data()[i] = std::abs(g(rng)) + 0.1 * g(rng);
  Eigen::VectorXd x(b);
  for (Eigen::Index i = 0; i < b; ++i) x[i] = g(rng);
  gram = s * s.transpose();
  h = s * x;
}

}  // namespace

TEST(Nnls, MatchesBruteForceEnumerationOfActiveSets) {
  std::mt19937_64 rng(11);
  int binding = 0;
  for (int k = 1; k <= 12; ++k)
    for (int trial = 0; trial < 40; ++trial) {
      Eigen::MatrixXd gram;
      Eigen::VectorXd h;
      random_problem(k, 31, rng, gram, h);
      const Eigen::VectorXd ref = nnls_brute_force(gram, h);
      const GramNnls solver(gram);
      Eigen::VectorXd c(k);
      const NnlsStatus st = solver.solve(h.data(), c.data());
      ASSERT_TRUE(st.converged);
      EXPECT_LE((c - ref).norm(), 1e-8 * std::max(1.0, ref.norm())) << "k=" << k << " trial " << trial;
      EXPECT_GE(c.minCoeff(), 0.0);
      binding += (ref.array() == 0).any();
    }
  EXPECT_GT(binding, 100);  // most problems have active constraints, so the test exercises them
}

TEST(Nnls, AnyHintGivesTheSameOptimum) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::MatrixXd gram;
    Eigen::VectorXd h;
    random_problem(6, 31, rng, gram, h);
    const GramNnls solver(gram);
    Eigen::VectorXd c0(6), c1(6);
    std::uint64_t p0 = 0;
    solver.solve(h.data(), c0.data(), p0);
    std::uint64_t hint = std::uint64_t(trial) % 64;
    solver.solve(h.data(), c1.data(), hint);
    EXPECT_LE((c0 - c1).norm(), 1e-10 * std::max(1.0, c0.norm()));
    EXPECT_EQ(hint, p0);  // the optimal passive set comes back as the next hint
  }
}

TEST(Nnls, UnconstrainedOptimumWhenItIsPositive) {
  Eigen::MatrixXd gram(2, 2);
  gram << 2, 1, 1, 2;
  Eigen::VectorXd h(2);
  h << 3, 3;  // G^{-1} h = (1, 1)
  const GramNnls solver(gram);
  Eigen::VectorXd c(2);
  solver.solve(h.data(), c.data());
  EXPECT_NEAR(c[0], 1.0, 1e-10);  // the solver's ridge is 1e-12 of the trace
  EXPECT_NEAR(c[1], 1.0, 1e-10);
  h << 3, -3;  // closed form: c = (1.5, 0)
  solver.solve(h.data(), c.data());
  EXPECT_NEAR(c[0], 1.5, 1e-10);
  EXPECT_EQ(c[1], 0.0);
}

TEST(Nnls, SingularGramStillGivesAFeasibleMinimiser) {
  // Two identical basis vectors: the optimum value is unique, the split between them is not.
  Eigen::MatrixXd gram = Eigen::MatrixXd::Ones(2, 2);
  Eigen::VectorXd h(2);
  h << 2, 2;
  const GramNnls solver(gram);
  Eigen::VectorXd c(2);
  solver.solve(h.data(), c.data());
  EXPECT_GE(c.minCoeff(), 0.0);
  EXPECT_NEAR(c.sum(), 2.0, 1e-6);
}

TEST(Nnls, RefusesMisuse) {
  EXPECT_THROW(GramNnls(Eigen::MatrixXd(2, 3)), UsageError);
  Eigen::MatrixXd bad = Eigen::MatrixXd::Identity(2, 2);
  bad(0, 0) = std::nan("");
  EXPECT_THROW(GramNnls{bad}, UsageError);
}
