#include "specula/core/nnls.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "specula/core/error.h"

namespace specula {
namespace {

constexpr std::size_t kMaxCached = 10;

// The indices of the set bits of mask, in order.
int members(std::uint64_t mask, int* idx) {
  int n = 0;
  while (mask) {
    idx[n++] = std::countr_zero(mask);
    mask &= mask - 1;
  }
  return n;
}

// The hinted passive set's product q = Q h (k known at compile time, so the loops unroll); true and c set
// when it is optimal.
template <std::size_t K>
bool try_hint(const double* q, const double* h, std::uint64_t mask, double tol, double* c) {
  double s[K];
  for (std::size_t i = 0; i < K; ++i) {
    double v = 0;
    for (std::size_t j = 0; j < K; ++j) v += q[i * K + j] * h[j];
    s[i] = v;
  }
  bool ok = true;
  for (std::size_t i = 0; i < K; ++i) ok &= ((mask >> i) & 1u) ? s[i] > 0 : s[i] <= tol;
  if (!ok) return false;
  for (std::size_t i = 0; i < K; ++i) c[i] = ((mask >> i) & 1u) ? s[i] : 0.0;
  return true;
}

template <std::size_t... K>
bool try_hint_k(std::size_t k, const double* q, const double* h, std::uint64_t mask, double tol, double* c,
                std::index_sequence<K...>) {
  bool result = false;
  ((k == K + 1 ? (result = try_hint<K + 1>(q, h, mask, tol, c), true) : false) || ...);
  return result;
}

}  // namespace

GramNnls::GramNnls(const Eigen::Ref<const Eigen::MatrixXd>& gram) : k_(std::size_t(gram.rows())), gram_(gram) {
  if (gram.rows() != gram.cols() || k_ < 1)
    throw UsageError("GramNnls: the Gram matrix must be square with at least one row, got " +
                     std::to_string(gram.rows()) + " x " + std::to_string(gram.cols()));
  if (!gram_.allFinite()) throw UsageError("GramNnls: the Gram matrix has non-finite entries");
  gram_ = 0.5 * (gram_ + gram_.transpose()).eval();
  const double ridge = 1e-12 * std::max(gram_.trace(), std::numeric_limits<double>::min());
  gram_.diagonal().array() += ridge;
  if (k_ > kMaxCached) return;
  // Per passive set P, Q (k x k, row-major) maps h to the unconstrained solution on P (rows in P) and to the
  // gradient h - G s at that solution (rows outside P): one product decides optimality.
  const std::uint64_t sets = std::uint64_t(1) << k_;
  const auto k = Eigen::Index(k_);
  inverses_.assign(sets * k_ * k_, 0.0);
  int idx[64];
  for (std::uint64_t m = 0; m < sets; ++m) {
    const int p = members(m, idx);
    Eigen::MatrixXd solve = Eigen::MatrixXd::Zero(k, k);  // s = solve * h
    if (p > 0) {
      Eigen::MatrixXd sub(p, p);
      for (int a = 0; a < p; ++a)
        for (int b = 0; b < p; ++b) sub(a, b) = gram_(idx[a], idx[b]);
      Eigen::LDLT<Eigen::MatrixXd> ldlt(sub);
      Eigen::MatrixXd inv = ldlt.solve(Eigen::MatrixXd::Identity(p, p));
      if (ldlt.info() != Eigen::Success || !inv.allFinite()) inv.setZero();
      for (int a = 0; a < p; ++a)
        for (int b = 0; b < p; ++b) solve(idx[a], idx[b]) = inv(a, b);
    }
    const Eigen::MatrixXd grad = Eigen::MatrixXd::Identity(k, k) - gram_ * solve;  // w = grad * h
    double* q = inverses_.data() + m * k_ * k_;
    for (Eigen::Index i = 0; i < k; ++i)
      for (Eigen::Index j = 0; j < k; ++j) q[i * k + j] = ((m >> i) & 1u) ? solve(i, j) : grad(i, j);
  }
  cached_ = true;
}

bool GramNnls::solve_passive(const char* in, std::uint64_t mask, const double* h, double* s, int* idx) const {
  if (cached_) {
    const double* q = inverses_.data() + mask * k_ * k_;
    for (std::size_t i = 0; i < k_; ++i) {
      double v = 0;
      for (std::size_t j = 0; j < k_; ++j) v += q[i * k_ + j] * h[j];
      s[i] = v;  // outside the passive set: the gradient there
    }
    return true;
  }
  int p = 0;
  for (std::size_t i = 0; i < k_; ++i) {
    s[i] = 0.0;
    if (in[i]) idx[p++] = int(i);
  }
  if (p == 0) return true;
  Eigen::MatrixXd sub(p, p);
  Eigen::VectorXd rhs(p);
  for (int a = 0; a < p; ++a) {
    rhs[a] = h[idx[a]];
    for (int b = 0; b < p; ++b) sub(a, b) = gram_(idx[a], idx[b]);
  }
  Eigen::LDLT<Eigen::MatrixXd> ldlt(sub);
  const Eigen::VectorXd x = ldlt.solve(rhs);
  if (ldlt.info() != Eigen::Success || !x.allFinite()) return false;
  for (int a = 0; a < p; ++a) s[idx[a]] = x[a];
  return true;
}

// KKT at the unconstrained solution s on passive set `in` (from solve_passive): s > 0 on the passive set,
// gradient h - G s <= tol off it. With the cache, s already holds that gradient off the passive set.
bool GramNnls::optimal(const char* in, const double* h, const double* s, double tol) const {
  for (std::size_t i = 0; i < k_; ++i) {
    if (in[i]) {
      if (!(s[i] > 0)) return false;
      continue;
    }
    double w = s[i];
    if (!cached_) {
      w = h[i];
      for (std::size_t j = 0; j < k_; ++j)
        if (in[j]) w -= gram_(Eigen::Index(i), Eigen::Index(j)) * s[j];
    }
    if (w > tol) return false;
  }
  return true;
}

// The gradient h - G c off the passive set into w (entries on it are not used); with the cache, s (from
// solve_passive) already holds it there.
void GramNnls::gradient(const char* in, const double* h, const double* c, const double* s, double* w) const {
  for (std::size_t i = 0; i < k_; ++i) {
    if (in[i]) continue;
    if (cached_) {
      w[i] = s[i];
      continue;
    }
    double v = h[i];
    for (std::size_t q = 0; q < k_; ++q) v -= gram_(Eigen::Index(i), Eigen::Index(q)) * c[q];
    w[i] = v;
  }
}

double GramNnls::tolerance(const double* h) const {
  double hmax = 0;
  for (std::size_t i = 0; i < k_; ++i) hmax = std::max(hmax, std::abs(h[i]));
  return 1e-11 * std::max(hmax, std::numeric_limits<double>::min());
}

void GramNnls::set_flags(char* in, std::uint64_t m) const {
  for (std::size_t i = 0; i < k_; ++i) in[i] = char((m >> i) & 1u);
}

// Warm start from the hint: drop its indices whose unconstrained solution is not positive until the rest
// is; that point (the minimiser on its passive set, positive there) is a valid state of the method. Returns
// its mask (0 when nothing of the hint remains), with c, t.in and t.w set for it.
std::uint64_t GramNnls::warm_start(const Work& t, const double* h, double* c, std::uint64_t hint,
                                   NnlsStatus& st) const {
  double *s = t.s, *w = t.w;
  char* in = t.in;
  int* idx = t.idx;
  std::uint64_t mask = 0;
  while (hint) {
    set_flags(in, hint);
    if (!solve_passive(in, hint, h, s, idx)) {
      set_flags(in, 0);
      break;
    }
    std::uint64_t drop = 0;
    for (std::size_t i = 0; i < k_; ++i)
      if (in[i] && !(s[i] > 0)) drop |= std::uint64_t(1) << i;
    if (!drop) {
      mask = hint;
      for (std::size_t i = 0; i < k_; ++i) c[i] = in[i] ? s[i] : 0.0;
      gradient(in, h, c, s, w);
      break;
    }
    hint &= ~drop;
    if (!hint) set_flags(in, 0);
    ++st.iterations;
  }
  return mask;
}

// After an index joined the passive set: solves on the set, stepping back from infeasible solutions and dropping
// the coefficients that reach zero, until the solution is positive (c set to it). False (st.converged false)
// when G_PP cannot be factored or the iterations pass `cap`.
bool GramNnls::make_feasible(const Work& t, const double* h, double* c, std::uint64_t& mask, int cap,
                             NnlsStatus& st) const {
  double* s = t.s;
  char* in = t.in;
  const bool masks = k_ <= 64;
  while (true) {
    if (!solve_passive(in, mask, h, s, t.idx)) {
      st.converged = false;
      return false;
    }
    bool feasible = true;
    for (std::size_t i = 0; i < k_; ++i)
      if (in[i] && s[i] <= 0) feasible = false;
    if (feasible) {
      for (std::size_t i = 0; i < k_; ++i) c[i] = in[i] ? s[i] : 0.0;
      return true;
    }
    // Step from c towards s until the first passive coefficient reaches zero; drop those at zero.
    double alpha = 1;
    int hit = -1;
    for (std::size_t i = 0; i < k_; ++i)
      if (in[i] && s[i] <= 0) {
        const double a = c[i] / (c[i] - s[i]);
        if (hit < 0 || a < alpha) {
          alpha = a;
          hit = int(i);
        }
      }
    for (std::size_t i = 0; i < k_; ++i) {
      if (!in[i]) continue;
      c[i] += alpha * (s[i] - c[i]);
      if (int(i) == hit || c[i] <= 0) {
        c[i] = 0;
        in[i] = 0;
        if (masks) mask &= ~(std::uint64_t(1) << i);
      }
    }
    if (++st.iterations > cap) {
      st.converged = false;
      return false;
    }
  }
}

NnlsStatus GramNnls::solve(const double* h, double* c, std::uint64_t& passive) const {
  NnlsStatus st;
  const double tol = tolerance(h);
  // Passive sets as flags `in`; for k <= 64 also as a mask (the hint, and the cache's index for k <= 10).
  const bool masks = k_ <= 64;
  const std::uint64_t all = !masks ? 0 : k_ == 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << k_) - 1;
  if (passive & ~all) passive = 0;
  // The hint: if the unconstrained solution on the hinted set is positive and optimal, it is the answer.
  if (passive && cached_ &&
      try_hint_k(k_, inverses_.data() + passive * k_ * k_, h, passive, tol, c, std::make_index_sequence<kMaxCached>{}))
    return st;
  double s_stack[64], w_stack[64];
  char in_stack[64];
  int idx_stack[64];
  std::vector<double> sw_heap;
  std::vector<char> in_heap;
  std::vector<int> idx_heap;
  Work t{s_stack, w_stack, in_stack, idx_stack};
  if (!masks) {
    sw_heap.resize(2 * k_);
    in_heap.resize(k_);
    idx_heap.resize(k_);
    t = Work{sw_heap.data(), sw_heap.data() + k_, in_heap.data(), idx_heap.data()};
  }
  double *s = t.s, *w = t.w;
  char* in = t.in;
  if (passive && !cached_) {
    set_flags(in, passive);
    if (solve_passive(in, passive, h, s, t.idx) && optimal(in, h, s, tol)) {
      for (std::size_t i = 0; i < k_; ++i) c[i] = in[i] ? s[i] : 0.0;
      return st;
    }
  }
  for (std::size_t i = 0; i < k_; ++i) {
    c[i] = 0;
    w[i] = h[i];
    in[i] = 0;
  }
  const int cap = 3 * int(k_) + 10;
  std::uint64_t mask = warm_start(t, h, c, passive, st);
  while (true) {
    int j = -1;
    double best = tol;
    for (std::size_t i = 0; i < k_; ++i)
      if (!in[i] && w[i] > best) {
        best = w[i];
        j = int(i);
      }
    if (j < 0) break;
    if (++st.iterations > cap) {
      st.converged = false;
      break;
    }
    in[j] = 1;
    if (masks) mask |= std::uint64_t(1) << j;
    if (!make_feasible(t, h, c, mask, cap, st)) break;
    gradient(in, h, c, s, w);
  }
  passive = mask;
  return st;
}

Eigen::VectorXd nnls_brute_force(const Eigen::MatrixXd& gram, const Eigen::VectorXd& h) {
  const Eigen::Index k = gram.rows();
  if (k < 1 || k > 16) throw UsageError("nnls_brute_force: k must be 1..16");
  Eigen::VectorXd best = Eigen::VectorXd::Zero(k);
  double best_f = 0;  // objective at c = 0
  for (std::uint64_t m = 1; m < (std::uint64_t(1) << k); ++m) {
    std::vector<Eigen::Index> idx;
    for (Eigen::Index i = 0; i < k; ++i)
      if ((m >> i) & 1u) idx.push_back(i);
    const auto p = Eigen::Index(idx.size());
    Eigen::MatrixXd sub(p, p);
    Eigen::VectorXd rhs(p);
    for (Eigen::Index a = 0; a < p; ++a) {
      rhs[a] = h[idx[std::size_t(a)]];
      for (Eigen::Index b = 0; b < p; ++b) sub(a, b) = gram(idx[std::size_t(a)], idx[std::size_t(b)]);
    }
    const Eigen::VectorXd x = sub.ldlt().solve(rhs);
    if ((x.array() < 0).any() || !x.allFinite()) continue;
    Eigen::VectorXd c = Eigen::VectorXd::Zero(k);
    for (Eigen::Index a = 0; a < p; ++a) c[idx[std::size_t(a)]] = x[a];
    const double f = 0.5 * c.dot(gram * c) - h.dot(c);
    if (f < best_f) {
      best_f = f;
      best = c;
    }
  }
  return best;
}

}  // namespace specula
