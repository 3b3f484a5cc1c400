#include "specula/nmf/nmf.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/nmf/checkpoint.h"
#include "specula/nmf/detail/passes.h"

namespace specula::nmf {
using namespace detail;
namespace {

using Clock = std::chrono::steady_clock;

// At most this many epochs on the warm-up sample.
constexpr std::size_t kWarmupEpochs = 100;

std::string fingerprint(const BlockReader& reader, const NmfOptions& o) {
  std::ostringstream f;
  f << "k=" << o.k << " init=" << (o.init == Init::nndsvd ? "nndsvd" : "random") << " seed=" << o.seed
    << " restarts=" << o.restarts << " warmup_blocks=" << o.warmup_blocks << " wave_blocks=" << o.wave_blocks
    << " negatives=" << (o.negatives == Negatives::clip ? "clip" : "reject") << " bands=" << reader.bands()
    << " spectra=" << reader.spectra() << " blocks=" << reader.block_count() << " sources=";
  for (const auto& n : reader.source_names()) f << n << ",";
  return f.str();
}

std::string describe_difference(const std::string& a, const std::string& b) {
  std::istringstream sa(a), sb(b);
  std::string x, y, out;
  while (sa >> x && sb >> y)
    if (x != y) out += (out.empty() ? "" : ", ") + y + " (checkpoint: " + x + ")";
  return out.empty() ? "the runs differ" : out;
}

void check_options(const BlockReader& reader, const NmfOptions& o) {
  if (o.k < 1 || o.k > reader.bands())
    throw UsageError("k = " + std::to_string(o.k) + ": give between 1 and " + std::to_string(reader.bands()) +
                     " components (the data has " + std::to_string(reader.bands()) + " bands)");
  if (o.restarts < 1 || o.restarts > 1000)
    throw UsageError("restarts " + std::to_string(o.restarts) + ": give 1 to 1000");
  if (o.max_epochs < 1) throw UsageError("max_epochs must be at least 1");
  if (o.wave_blocks < 1 || o.wave_blocks > 1000000)
    throw UsageError("wave_blocks " + std::to_string(o.wave_blocks) + ": give 1 to 1000000 blocks per basis update");
  if (!(o.tol >= 0) || !std::isfinite(o.tol)) throw UsageError("tol must be a finite number >= 0");
  if (reader.spectra() == 0) throw InputError("the selection holds no valid spectra");
  if (o.resume && o.checkpoint.empty()) throw UsageError("resume needs a checkpoint path");
}

// Where the run starts: the checkpoint resumed, or a fresh one from the X^T X pass. Fills the result's counts,
// second moment, SVD bound and the restarts the checkpoint finished.
Checkpoint start_run(const BlockReader& reader, const NmfOptions& o, const Collective& ranks, NmfResult& result) {
  const auto b = Eigen::Index(reader.bands());
  const auto k = Eigen::Index(o.k);
  const std::string print = fingerprint(reader, o);
  Checkpoint cp;
  bool resumed = false;
  if (o.resume) {
    cp = load_checkpoint(o.checkpoint);
    if (cp.fingerprint != print)
      throw UsageError(o.checkpoint.string() +
                       ": the checkpoint is of another run: " + describe_difference(cp.fingerprint, print) +
                       "; rerun with the same options, or start afresh instead of resuming");
    resumed = true;
  } else {
    const GramStats g = gram_pass(ranks, reader, o.negatives);
    ++result.passes;
    cp.fingerprint = print;
    cp.gram = g.gram;
    cp.n = g.n;
    cp.negatives = g.negatives;
    cp.values = g.n * std::uint64_t(b);
  }
  result.resumed = resumed;
  result.n = cp.n;
  result.negatives = cp.negatives;
  result.values = cp.values;
  result.second_moment = cp.gram / double(std::max<std::uint64_t>(cp.n, 1));
  {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cp.gram, Eigen::EigenvaluesOnly);
    const Eigen::VectorXd ev = eig.eigenvalues().cwiseMax(0.0);  // ascending
    const double total = ev.sum();
    result.svd_bound = total > 0 ? std::sqrt(ev.head(b - k).sum() / total) : 0.0;
  }

  for (std::size_t r = 0; r < cp.done_bases.size(); ++r) {
    RestartResult rr;
    rr.basis = cp.done_bases[r];
    rr.history = cp.done_histories[r];
    rr.epochs = rr.history.size();
    rr.rel_error = rr.history.empty() ? 1.0 : rr.history.back();
    rr.converged = cp.done_converged[r] != 0;
    result.restarts.push_back(std::move(rr));
  }
  return cp;
}

// One restart: block-coordinate descent in waves. Each wave's coefficients are solved exactly for the current
// basis, then the basis is solved exactly from every wave's latest statistics. Those statistics are exact for
// the coefficients currently held (implicitly) for every spectrum, so the error they give is certified and never
// increases. A resumed run restarts from the epoch's end, where all waves are current. Every finished epoch is
// saved in the checkpoint.
class Restart {
 public:
  Restart(const BlockReader& reader, const NmfOptions& o, const Collective& ranks, NmfResult& result, Checkpoint& cp,
          std::size_t r, Clock::time_point start)
      : reader_(reader),
        o_(o),
        ranks_(ranks),
        result_(result),
        cp_(cp),
        r_(r),
        start_(start),
        k_(Eigen::Index(o.k)),
        b_(Eigen::Index(reader.bands())),
        wave_(o.wave_blocks),
        n_waves_((reader.block_count() + wave_ - 1) / wave_),
        rng_(o.seed * 1000003 + r),
        waves_(n_waves_, zero()),
        seen_(n_waves_, 0) {}

  RestartResult run() {
    const bool continues = result_.resumed && r_ == cp_.restart && cp_.epoch > 0;
    if (continues) {
      s_ = cp_.basis;
      history_ = cp_.history;
      if (s_.rows() != k_ || s_.cols() != b_)
        throw InputError(o_.checkpoint.string() + ": checkpoint basis has the wrong shape; delete it and start afresh");
      restore_waves();
    } else if (r_ == 0 && o_.init == Init::nndsvd) {
      s_ = nndsvd_init(ranks_, reader_, cp_.gram, k_, o_.negatives, o_.seed, result_.passes);
    } else {
      s_ = random_init(k_, b_, o_.seed + r_);
    }
    warm_up();
    bool converged = false;
    while (history_.size() < o_.max_epochs) {
      const std::size_t epoch = history_.size() + 1;
      Progress progress("nmf: restart " + std::to_string(r_ + 1) + " epoch " + std::to_string(epoch),
                        reader_.spectra());
      run_epoch(waves_, seen_, 1, progress);
      ++result_.passes;
      const double err = certified_error(total_of(), s_);
      const double prev = history_.empty() ? std::numeric_limits<double>::infinity() : history_.back();
      history_.push_back(err);
      if (o_.on_epoch) o_.on_epoch({r_, epoch, err, std::chrono::duration<double>(Clock::now() - start_).count()});
      save_epoch();
      if (prev - err <= o_.tol * err) {
        converged = true;
        break;
      }
      check_interrupt();
    }
    RestartResult rr;
    rr.basis = s_;
    rr.history = history_;
    rr.epochs = history_.size();
    rr.rel_error = history_.back();
    rr.converged = converged;
    return rr;
  }

 private:
  EpochStats zero() const { return EpochStats{Eigen::MatrixXd::Zero(k_, k_), Eigen::MatrixXd::Zero(k_, b_)}; }

  void restore_waves() {
    if (cp_.wave_xx.size() != n_waves_)
      throw InputError(o_.checkpoint.string() + ": checkpoint holds " + std::to_string(cp_.wave_xx.size()) +
                       " waves, this run has " + std::to_string(n_waves_) + "; delete it and start afresh");
    for (std::size_t w = 0; w < n_waves_; ++w) {
      waves_[w].ctc = Eigen::Map<const Eigen::MatrixXd>(cp_.wave_ctc.row(Eigen::Index(w)).data(), k_, k_);
      waves_[w].ctx = Eigen::Map<const Eigen::MatrixXd>(cp_.wave_ctx.row(Eigen::Index(w)).data(), k_, b_);
      waves_[w].xx = cp_.wave_xx[w];
      seen_[w] = 1;
    }
  }

  EpochStats total_of() const {
    EpochStats t = zero();
    for (std::size_t w = 0; w < n_waves_; ++w)
      if (seen_[w]) t += waves_[w];
    return t;
  }

  // One epoch of block-coordinate descent over the blocks first, first + stride, ... in waves of `wave` blocks.
  void run_epoch(std::vector<EpochStats>& ws, std::vector<char>& on, std::size_t step, Progress& progress) {
    for (std::size_t w = 0; w < ws.size(); ++w) {
      const std::size_t first = w * wave_ * step;
      const std::size_t last = std::min(reader_.block_count(), first + wave_ * step);
      ws[w] = coefficient_pass(ranks_, reader_, s_, o_.negatives, first, last, progress, step);
      on[w] = 1;
      result_.nnls_unconverged += ws[w].unconverged;
      EpochStats t = zero();
      for (std::size_t v = 0; v < ws.size(); ++v)
        if (on[v]) t += ws[v];
      s_ = solve_basis(t);
      const Eigen::VectorXd d = normalise_rows(s_, rng_);
      for (std::size_t v = 0; v < ws.size(); ++v)
        if (on[v]) rescale(ws[v], d);
    }
  }

  // Warm-up on a sample of whole blocks (every stride-th, about warmup_blocks of them) when the data is
  // large: the same descent on the sample until it stalls moves the basis close to its optimum at a small
  // fraction of a pass, so the full epochs start near it. Skipped on resume.
  void warm_up() {
    const std::size_t stride = o_.warmup_blocks ? reader_.block_count() / o_.warmup_blocks : 0;
    if (stride < 2 || !history_.empty()) return;
    const std::size_t sample = (reader_.block_count() + stride - 1) / stride;
    std::vector<EpochStats> ws((sample + wave_ - 1) / wave_, zero());
    std::vector<char> on(ws.size(), 0);
    double prev = std::numeric_limits<double>::infinity();
    for (std::size_t e = 0; e < kWarmupEpochs; ++e) {
      Progress progress("nmf: restart " + std::to_string(r_ + 1) + " warm-up " + std::to_string(e + 1),
                        reader_.spectra() / stride);
      run_epoch(ws, on, stride, progress);
      EpochStats t = zero();
      for (const auto& x : ws) t += x;
      const double err = certified_error(t, s_);
      result_.warmup_epochs = e + 1;
      result_.warmup_pass_equivalent += double(sample) / double(reader_.block_count());
      if (prev - err <= 1e-4 * err) break;
      prev = err;
    }
    result_.warmup_blocks = sample;
  }

  void save_epoch() {
    cp_.restart = r_;
    cp_.epoch = history_.size();
    cp_.basis = s_;
    cp_.history = history_;
    cp_.wave_ctc.resize(Eigen::Index(n_waves_), k_ * k_);
    cp_.wave_ctx.resize(Eigen::Index(n_waves_), k_ * b_);
    cp_.wave_xx.resize(n_waves_);
    for (std::size_t w = 0; w < n_waves_; ++w) {
      cp_.wave_ctc.row(Eigen::Index(w)) = Eigen::Map<const Eigen::RowVectorXd>(waves_[w].ctc.data(), k_ * k_);
      cp_.wave_ctx.row(Eigen::Index(w)) = Eigen::Map<const Eigen::RowVectorXd>(waves_[w].ctx.data(), k_ * b_);
      cp_.wave_xx[w] = waves_[w].xx;
    }
    if (!o_.checkpoint.empty() && ranks_.rank() == 0) save_checkpoint(o_.checkpoint, cp_);
  }

  const BlockReader& reader_;
  const NmfOptions& o_;
  const Collective& ranks_;
  NmfResult& result_;
  Checkpoint& cp_;
  const std::size_t r_;
  const Clock::time_point start_;
  const Eigen::Index k_, b_;
  const std::size_t wave_, n_waves_;
  std::mt19937_64 rng_;
  Eigen::MatrixXd s_;
  std::vector<double> history_;
  std::vector<EpochStats> waves_;
  std::vector<char> seen_;
};

// Marks restart r finished in the checkpoint, saved unless it was the last.
void finish_restart(const NmfOptions& o, const Collective& ranks, Checkpoint& cp, std::size_t r,
                    const RestartResult& rr) {
  cp.done_bases.push_back(rr.basis);
  cp.done_histories.push_back(rr.history);
  cp.done_converged.push_back(rr.converged);
  cp.restart = r + 1;
  cp.epoch = 0;
  cp.history.clear();
  cp.wave_ctc.resize(0, 0);
  cp.wave_ctx.resize(0, 0);
  cp.wave_xx.clear();
  cp.basis = rr.basis;
  if (!o.checkpoint.empty() && ranks.rank() == 0 && r + 1 < o.restarts) save_checkpoint(o.checkpoint, cp);
}

// The best restart, every restart's angles to it, and the certifying pass: the best basis's exact coefficients
// give its own error and the RMS coefficient of each component.
void certify_best(const BlockReader& reader, const NmfOptions& o, const Collective& ranks, NmfResult& result) {
  const auto b = Eigen::Index(reader.bands());
  const auto k = Eigen::Index(o.k);
  std::size_t best = 0;
  for (std::size_t r = 1; r < result.restarts.size(); ++r)
    if (result.restarts[r].rel_error < result.restarts[best].rel_error) best = r;
  result.best = best;
  for (auto& rr : result.restarts)
    std::tie(rr.mean_angle_deg, rr.max_angle_deg) = basis_angles(rr.basis, result.restarts[best].basis);
  Progress progress("nmf: certifying pass", reader.spectra());
  EpochStats fin{Eigen::MatrixXd::Zero(k, k), Eigen::MatrixXd::Zero(k, b)};
  const Share share = share_of(ranks, reader.block_count());
  for (std::size_t first = share.first; first < share.last; first += kRangeBlocks)
    fin += coefficient_pass(single_process(), reader, result.restarts[best].basis, o.negatives, first,
                            std::min(share.last, first + kRangeBlocks), progress);
  sum_over_ranks(ranks, fin);
  ++result.passes;
  result.nnls_unconverged += fin.unconverged;
  result.rel_error = certified_error(fin, result.restarts[best].basis);
  result.weights = (fin.ctc.diagonal() / double(std::max<std::uint64_t>(result.n, 1))).cwiseSqrt();
}

}  // namespace

Init parse_init(const std::string& s) {
  if (s == "nndsvd") return Init::nndsvd;
  if (s == "random") return Init::random;
  throw UsageError("init '" + s + "': choose nndsvd or random");
}

Negatives parse_negatives(const std::string& s) {
  if (s == "clip") return Negatives::clip;
  if (s == "reject") return Negatives::reject;
  throw UsageError("negatives '" + s + "': choose clip (clip to zero and count) or reject");
}

std::pair<double, double> basis_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.rows() == 0)
    throw UsageError("basis_angles: bases of different shapes");
  const Eigen::Index k = a.rows();
  Eigen::MatrixXd cosine(k, k);
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index j = 0; j < k; ++j) {
      const double na = a.row(i).norm(), nb = b.row(j).norm();
      cosine(i, j) = na > 0 && nb > 0 ? std::clamp(a.row(i).dot(b.row(j)) / (na * nb), -1.0, 1.0) : 0.0;
    }
  std::vector<Eigen::Index> perm(static_cast<std::size_t>(k)), best;
  std::iota(perm.begin(), perm.end(), Eigen::Index(0));
  if (k <= 8) {
    double best_sum = -1e300;
    do {
      double sum = 0;
      for (Eigen::Index i = 0; i < k; ++i) sum += cosine(i, perm[std::size_t(i)]);
      if (sum > best_sum) {
        best_sum = sum;
        best = perm;
      }
    } while (std::next_permutation(perm.begin(), perm.end()));
  } else {
    best.assign(std::size_t(k), -1);
    std::vector<bool> used_a(static_cast<std::size_t>(k)), used_b(static_cast<std::size_t>(k));
    for (Eigen::Index step = 0; step < k; ++step) {
      Eigen::Index bi = -1, bj = -1;
      for (Eigen::Index i = 0; i < k; ++i)
        for (Eigen::Index j = 0; j < k; ++j)
          if (!used_a[std::size_t(i)] && !used_b[std::size_t(j)] && (bi < 0 || cosine(i, j) > cosine(bi, bj))) {
            bi = i;
            bj = j;
          }
      used_a[std::size_t(bi)] = used_b[std::size_t(bj)] = true;
      best[std::size_t(bi)] = bj;
    }
  }
  double sum = 0, worst = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    const double deg = std::acos(cosine(i, best[std::size_t(i)])) * 180.0 / M_PI;
    sum += deg;
    worst = std::max(worst, deg);
  }
  return {sum / double(k), worst};
}

NmfResult factorize(const BlockReader& reader, const NmfOptions& o, const Collective& ranks) {
  check_options(reader, o);
  const auto start = Clock::now();
  NmfResult result;
  Checkpoint cp = start_run(reader, o, ranks, result);
  try {
    for (std::size_t r = cp.restart; r < o.restarts; ++r) {
      RestartResult rr = Restart(reader, o, ranks, result, cp, r, start).run();
      finish_restart(o, ranks, cp, r, rr);
      result.restarts.push_back(std::move(rr));
    }
  } catch (const Interrupted&) {
    const std::string kept = std::to_string(cp.epoch) + " finished epoch" + (cp.epoch == 1 ? "" : "s") +
                             " of restart " + std::to_string(cp.restart + 1);
    throw Interrupted("interrupted; " + (o.checkpoint.empty() ? kept + " were not saved (no checkpoint)"
                                                              : kept + " kept in " + o.checkpoint.string() +
                                                                    ": resume from it to continue"));
  }
  certify_best(reader, o, ranks, result);
  return result;
}

}  // namespace specula::nmf
