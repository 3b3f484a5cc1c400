#include "specula/core/nnls.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <random>
#include <vector>

#include "specula/core/error.h"

using namespace specula;

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

// KKT of min 1/2 c^T G c - h^T c, c >= 0, checked directly: c >= 0, gradient h - G c zero where c > 0 and
// <= 0 where c = 0 (to tol relative to max |h|).
void expect_kkt(const Eigen::MatrixXd& gram, const Eigen::VectorXd& h, const Eigen::VectorXd& c, double rel) {
  const Eigen::VectorXd w = h - gram * c;
  const double tol = rel * std::max(1.0, h.cwiseAbs().maxCoeff());
  ASSERT_GE(c.minCoeff(), 0.0);
  for (Eigen::Index i = 0; i < c.size(); ++i) {
    if (c[i] > 0) {
      EXPECT_NEAR(w[i], 0.0, tol) << i;
    } else {
      EXPECT_LE(w[i], tol) << i;
    }
  }
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

// Least squares min ||M x - b||, x >= 0 in normal form (as the bounded RGB uplift poses it): brute force over every
// column subset solved by QR on M itself, independently of the Gram matrix.
TEST(Nnls, NormalEquationsMatchBruteForceOverColumnSubsets) {
  std::mt19937 rng(31);
  std::normal_distribution<double> g(0, 1);
  for (int trial = 0; trial < 30; ++trial) {
    Eigen::MatrixXd m(9, 6);
    Eigen::VectorXd b(9);
    for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = g(rng);
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = g(rng);
    const Eigen::MatrixXd gram = m.transpose() * m;
    const Eigen::VectorXd h = m.transpose() * b;
    Eigen::VectorXd x(6);
    ASSERT_TRUE(GramNnls(gram).solve(h.data(), x.data()).converged);
    double best = 1e300;
    Eigen::VectorXd best_x;
    for (int mask = 0; mask < 64; ++mask) {
      std::vector<Eigen::Index> cols;
      for (Eigen::Index j = 0; j < 6; ++j)
        if (mask >> j & 1) cols.push_back(j);
      Eigen::VectorXd cand = Eigen::VectorXd::Zero(6);
      if (!cols.empty()) {
        Eigen::MatrixXd sub(9, Eigen::Index(cols.size()));
        for (std::size_t c = 0; c < cols.size(); ++c) sub.col(Eigen::Index(c)) = m.col(cols[c]);
        const Eigen::VectorXd s = sub.colPivHouseholderQr().solve(b);
        if (s.minCoeff() < 0) continue;
        for (std::size_t c = 0; c < cols.size(); ++c) cand[cols[c]] = s[Eigen::Index(c)];
      }
      const double r = (m * cand - b).norm();
      if (r < best) {
        best = r;
        best_x = cand;
      }
    }
    EXPECT_NEAR((m * x - b).norm(), best, 1e-10) << trial;
    EXPECT_LT((x - best_x).cwiseAbs().maxCoeff(), 1e-8) << trial;
  }
}

// Beyond the cached sizes and beyond 64 unknowns (a 1 nm uplift has 301): the answer meets the KKT conditions,
// and a hint (ignored above 64) changes nothing.
TEST(Nnls, LargeProblemsMeetTheKktConditions) {
  std::mt19937_64 rng(7);
  for (int k : {11, 31, 64, 65, 150}) {
    Eigen::MatrixXd gram;
    Eigen::VectorXd h;
    random_problem(k, 2 * k + 5, rng, gram, h);
    const GramNnls solver(gram);
    Eigen::VectorXd c(k), again(k);
    std::uint64_t passive = 0;
    const NnlsStatus st = solver.solve(h.data(), c.data(), passive);
    ASSERT_TRUE(st.converged) << k;
    expect_kkt(gram, h, c, 1e-8);
    EXPECT_GT((c.array() == 0).count(), 0) << "k=" << k << ": no constraint binds";
    if (k > 64) {
      EXPECT_EQ(passive, 0u);
    }
    std::uint64_t hint = k > 64 ? ~std::uint64_t(0) : passive;
    solver.solve(h.data(), again.data(), hint);
    EXPECT_LE((c - again).norm(), 1e-10 * std::max(1.0, c.norm())) << k;
  }
}

TEST(Nnls, SolutionsMeetTheKktConditions) {
  std::mt19937_64 rng(3);
  for (int k = 1; k <= 10; ++k)
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::MatrixXd gram;
      Eigen::VectorXd h;
      random_problem(k, 31, rng, gram, h);
      Eigen::VectorXd c(k);
      GramNnls(gram).solve(h.data(), c.data());
      expect_kkt(gram, h, c, 1e-9);
    }
}
