#pragma once
// Non-negative least squares in Gram form: min_c 1/2 c^T G c - h^T c subject to c >= 0, with G = S S^T
// symmetric positive (semi)definite and h = S x. Solved exactly by the active-set method of Lawson and
// Hanson in the normal-equation form of Bro and de Jong (1997): every step solves the unconstrained
// problem on the current passive set; the result satisfies the KKT conditions to a relative tolerance.
// The one NNLS of specula (core, Eigen only): NMF's coefficient and basis steps, projection onto an NMF basis
// (stats/project.h) and the bounded RGB uplift (codec/uplift.h) all solve with it.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace specula {

/// Outcome of one NNLS solve.
struct NnlsStatus {
  int iterations = 0;     ///< passive-set changes
  bool converged = true;  ///< false if the iteration cap was reached (c is then feasible but not optimal)
};

/// An NNLS solver for one Gram matrix G (k x k), reused for many right-hand sides. For k <= 10 the inverses
/// of G restricted to every passive set are computed once, so a solve costs a few k x k products (one when the
/// hinted passive set is optimal).
class GramNnls {
 public:
  /// Prepares G (symmetric, k x k, k >= 1). A tiny ridge (1e-12 of the trace) keeps singular G solvable.
  explicit GramNnls(const Eigen::Ref<const Eigen::MatrixXd>& gram);
  /// The number of unknowns k.
  std::size_t k() const { return k_; }
  /// The KKT tolerance solve() applies for right-hand side h (length k): a gradient entry off the passive set
  /// counts as positive only above it (1e-11 of max |h_i|).
  double tolerance(const double* h) const;
  /// G as solved: symmetrised, with the ridge added.
  const Eigen::MatrixXd& gram() const { return gram_; }
  /// Solves for c (length k) given h (length k). `passive` is a passive-set mask to try first (e.g. the
  /// previous spectrum's); the returned mask is the optimal passive set, usable as the next hint (k <= 64;
  /// for larger k it is ignored and set to 0).
  NnlsStatus solve(const double* h, double* c, std::uint64_t& passive) const;
  /// Solves for c from scratch (no hint).
  NnlsStatus solve(const double* h, double* c) const {
    std::uint64_t p = 0;
    return solve(h, c, p);
  }

 private:
  // Unconstrained solution on the passive set (flags `in`, as a mask `mask` for the cache) into s (entries
  // outside the set: zero, or with the cache the gradient there); idx is scratch of k; false if G_PP could not
  // be factored.
  bool solve_passive(const char* in, std::uint64_t mask, const double* h, double* s, int* idx) const;
  bool optimal(const char* in, const double* h, const double* s, double tol) const;
  void gradient(const char* in, const double* h, const double* c, const double* s, double* w) const;
  // Scratch of one solve, each of k: the unconstrained solution, the gradient, the passive flags, an index list.
  struct Work {
    double* s;
    double* w;
    char* in;
    int* idx;
  };
  void set_flags(char* in, std::uint64_t m) const;
  std::uint64_t warm_start(const Work& t, const double* h, double* c, std::uint64_t hint, NnlsStatus& st) const;
  bool make_feasible(const Work& t, const double* h, double* c, std::uint64_t& mask, int cap, NnlsStatus& st) const;

  std::size_t k_;
  Eigen::MatrixXd gram_;
  bool cached_ = false;
  std::vector<double> inverses_;  // per mask: k x k, see the constructor
};

/// Reference NNLS by enumerating all 2^k passive sets and keeping the feasible KKT point (for tests; k <= 16).
Eigen::VectorXd nnls_brute_force(const Eigen::MatrixXd& gram, const Eigen::VectorXd& h);

}  // namespace specula
