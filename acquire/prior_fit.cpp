// A learned BRDF prior (acquire/prior.h) fitted to observations: their weights, the normal equations streamed block
// by block of the prior's components, and the fit mapped back onto the grid.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/store/prior.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kBlock = 8192;        // observations per piece of the normal equations
constexpr std::size_t kPiecesInFlight = 8;  // pieces made at once: bounds the k x k partial sums held

}  // namespace

PriorWeights parse_prior_weights(std::string_view name) {
  if (name == "noise") return PriorWeights::noise;
  if (name == "count") return PriorWeights::count;
  if (name == "scatter") return PriorWeights::scatter;
  throw UsageError("prior weights '" + std::string(name) + "': use noise, count or scatter");
}

std::string_view prior_weights_name(PriorWeights w) {
  switch (w) {
    case PriorWeights::noise:
      return "noise";
    case PriorWeights::count:
      return "count";
    case PriorWeights::scatter:
      return "scatter";
  }
  return "noise";
}

std::vector<double> observation_weights(const BrdfPrior& p, const PriorObservations& obs, const PriorFitOptions& o) {
  const std::size_t n = obs.cell.size(), b = p.wavelengths.size(), c = p.channels();
  if (obs.weight.size() != n || obs.values.size() != n * b || !(obs.spread.empty() || obs.spread.size() == n * b))
    throw UsageError("prior: observation sizes do not match the prior's " + std::to_string(b) + " bands");
  if (!(o.noise_shrinkage >= 0) || !std::isfinite(o.noise_shrinkage) || !(o.noise_floor > 0) || !(o.noise_floor <= 1))
    throw UsageError("prior: noise_shrinkage must be finite and >= 0, noise_floor in (0, 1]");
  std::vector<double> w(obs.weight.begin(), obs.weight.end());
  if (o.weights == PriorWeights::count || obs.spread.empty()) return w;
  const auto& cosines = valid_cell_cosines();
  const Eigen::MatrixXd proj = hat_projection(hat_basis(p.wavelengths, p.knots));
  const Eigen::MatrixXd proj2 = proj.cwiseAbs2();
  // Per cell the per-sample variance of the mapped value (delta method, bands independent), averaged over channels.
  std::vector<double> s2(n, -1.0);
  parallel_for(
      n,
      [&](std::size_t s) {
        if (!(obs.weight[s] >= (obs.spread_is_noise ? 1 : 2)) || obs.cell[s] >= cosines.size()) return;
        const double cw = cosines[obs.cell[s]];
        const Eigen::Map<const Eigen::VectorXf> mean(&obs.values[s * b], Eigen::Index(b));
        const Eigen::Map<const Eigen::VectorXf> spread(&obs.spread[s * b], Eigen::Index(b));
        const Eigen::ArrayXd ch = (proj * mean.cast<double>()).cwiseMax(0.0).array() * cw;
        const Eigen::ArrayXd var = (proj2 * spread.cast<double>().cwiseMax(0.0)).array() * cw * cw;
        s2[s] = (var / (ch + p.epsilon).square()).sum() / double(c);
      },
      4096);
  std::vector<double> known;
  for (const double v : s2)
    if (v >= 0) known.push_back(v);
  if (known.empty()) return w;
  std::nth_element(known.begin(), known.begin() + std::ptrdiff_t(known.size() / 2), known.end());
  const double sigma0 = known[known.size() / 2];
  if (!(sigma0 > 0) || !std::isfinite(sigma0)) return w;  // noiseless samples: nothing to tell the cells apart
  for (std::size_t s = 0; s < n; ++s) {
    const double dof = std::max(0.0, double(obs.weight[s]) - 1), own = s2[s] >= 0 ? s2[s] : sigma0;
    double var = obs.spread_is_noise ? own : (o.noise_shrinkage * sigma0 + dof * own) / (o.noise_shrinkage + dof);
    if (!obs.spread_is_noise && !(o.noise_shrinkage + dof > 0)) var = sigma0;
    w[s] *= sigma0 / std::max(var, o.noise_floor * sigma0);
  }
  return w;
}

namespace {

// What both passes of a fit share: the prior's tables, the observations in cell order and their weights.
struct Fit {
  const BrdfPrior& p;
  const PriorObservations& obs;
  std::vector<double> weight;
  std::vector<std::uint32_t> order;  // positions into obs, by cell (stable)
  Eigen::MatrixXd hats, proj;
  std::size_t k = 0, c = 0, b = 0, d = 0;
};

// Observations order[s0, s1), all in one block of store::kPriorBlockCells cells.
struct Piece {
  std::size_t s0 = 0, s1 = 0;
};

// A thread's storage for the pieces it makes, reused from piece to piece so its pages are faulted in once a fit.
struct PieceScratch {
  Buffer<double> qm, y, wq;  // rows x k, rows x c, rows x k, column-major
  std::vector<double> w;
  std::vector<std::size_t> at;  // each observation's cell in the block
};

// The scratch of the threads at work, kept for the whole fit: each parallel loop's threads lease one apiece.
class ScratchPool {
 public:
  struct Lease {
    explicit Lease(ScratchPool& p) : pool(p), scratch(p.take()) {}
    ~Lease() { pool.give(scratch); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ScratchPool& pool;
    PieceScratch* scratch;
  };

 private:
  PieceScratch* take() {
    const std::lock_guard lock(mutex_);
    if (free_.empty()) return all_.emplace_back(std::make_unique<PieceScratch>()).get();
    PieceScratch* s = free_.back();
    free_.pop_back();
    return s;
  }
  void give(PieceScratch* s) {
    const std::lock_guard lock(mutex_);
    free_.push_back(s);
  }
  std::mutex mutex_;
  std::vector<std::unique_ptr<PieceScratch>> all_;
  std::vector<PieceScratch*> free_;
};

// One piece's normal equations: k x k (lower triangle) and k x c.
struct PieceSums {
  Eigen::MatrixXd pa, pb;
};

// The weighted normal equations of one piece into out, made in s; q holds the k x count components of the block of
// cells from i0. Rows are scaled by sqrt(w), so pa is a symmetric rank update: half the product's work.
void piece_equations(const Fit& f, Piece piece, std::size_t i0, std::size_t count, std::span<const float> q,
                     PieceScratch& s, PieceSums& out) {
  using Matrix = Eigen::Map<Eigen::MatrixXd>;
  const auto& cosines = valid_cell_cosines();
  const std::size_t rows = piece.s1 - piece.s0;
  s.qm.resize(rows * f.k);
  s.wq.resize(rows * f.k);
  s.y.resize(rows * f.c);
  s.w.resize(rows);
  s.at.resize(rows);
  const Eigen::Index n = Eigen::Index(rows), k = Eigen::Index(f.k);
  Matrix qm(s.qm.data(), n, k), wq(s.wq.data(), n, k), y(s.y.data(), n, Eigen::Index(f.c));
  const Eigen::Map<const Eigen::VectorXd> w(s.w.data(), n);
  for (std::size_t r = 0; r < rows; ++r) {
    const std::size_t o = f.order[piece.s0 + r], i = f.obs.cell[o];
    s.at[r] = i - i0;
    const Eigen::Map<const Eigen::VectorXf> spec(&f.obs.values[o * f.b], Eigen::Index(f.b));
    const Eigen::VectorXd ch = (f.proj * spec.cast<double>()).cwiseMax(0.0) * double(cosines[i]);
    for (std::size_t j = 0; j < f.c; ++j)
      y(Eigen::Index(r), Eigen::Index(j)) =
          double(prior_mapped(float(ch[Eigen::Index(j)]), f.p.reference[i], f.p.epsilon)) - f.p.mean[i];
    s.w[r] = std::sqrt(f.weight[o]);
  }
  for (std::size_t j = 0; j < f.k; ++j)  // component by component: the cells ascend along q's rows
    for (std::size_t r = 0; r < rows; ++r) qm(Eigen::Index(r), Eigen::Index(j)) = q[j * count + s.at[r]];
  wq = w.asDiagonal() * qm;
  out.pa.setZero(k, k);
  out.pa.selfadjointView<Eigen::Lower>().rankUpdate(wq.transpose());
  out.pb = wq.transpose() * (w.asDiagonal() * y);
}

// Adds the normal equations of the observations in cells [i0, i0 + count) (components q) to ata's lower half and to
// atb: pieces of at most kBlock observations within one store::kPriorBlockCells block of cells, made on every thread
// in groups and summed in cell order, so the sums do not depend on the thread count or the block size. next: the
// first observation (in cell order) not yet added. pool and sums (one per piece in flight) are kept across the calls
// of a fit.
void add_equations(const Fit& f, std::size_t i0, std::size_t count, std::span<const float> q, std::size_t& next,
                   ScratchPool& pool, std::vector<PieceSums>& sums, Eigen::MatrixXd& ata, Eigen::MatrixXd& atb) {
  std::vector<Piece> pieces;
  for (std::size_t first = i0; first < i0 + count; first += store::kPriorBlockCells) {
    const std::size_t end = std::min(first + store::kPriorBlockCells, i0 + count);
    std::size_t s1 = next;
    while (s1 < f.order.size() && f.obs.cell[f.order[s1]] < end) ++s1;
    for (std::size_t s = next; s < s1; s += kBlock) pieces.push_back({s, std::min(s1, s + kBlock)});
    next = s1;
  }
  for (std::size_t g0 = 0; g0 < pieces.size(); g0 += kPiecesInFlight) {
    const std::size_t n = std::min(kPiecesInFlight, pieces.size() - g0);
    parallel_for(
        n, [&] { return ScratchPool::Lease(pool); },
        [&](std::size_t t, ScratchPool::Lease& lease) {
          piece_equations(f, pieces[g0 + t], i0, count, q, *lease.scratch, sums[t]);
        });
    for (std::size_t t = 0; t < n; ++t) {
      ata.triangularView<Eigen::Lower>() += sums[t].pa;
      atb += sums[t].pb;
    }
  }
}

// The fitted coefficients a (k x c) mapped back into grid at the cells i0 + cell[t] of the block [i0, i0 + count)
// (components q).
void reconstruct(const Fit& f, const Eigen::MatrixXd& a, std::size_t i0, std::size_t count,
                 std::span<const std::uint32_t> cell, std::span<const float> q, std::span<float> grid) {
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  constexpr std::size_t tile = 64;  // cells whose components are gathered at once, row by row of q
  parallel_for((cell.size() + tile - 1) / tile, [&](std::size_t blk) {
    const std::size_t r0 = blk * tile, n = std::min(cell.size(), r0 + tile) - r0;
    Eigen::MatrixXd qt(static_cast<Eigen::Index>(f.k), static_cast<Eigen::Index>(n));
    for (std::size_t j = 0; j < f.k; ++j)
      for (std::size_t t = 0; t < n; ++t) qt(Eigen::Index(j), Eigen::Index(t)) = q[j * count + cell[r0 + t]];
    Eigen::VectorXd y(static_cast<Eigen::Index>(f.c)), qi(static_cast<Eigen::Index>(f.k));
    for (std::size_t t = 0; t < n; ++t) {
      const std::size_t i = i0 + cell[r0 + t];
      qi = qt.col(Eigen::Index(t));
      const Eigen::VectorXd mapped_y = (a.transpose() * qi).array() + double(f.p.mean[i]);
      const double cw = std::max(double(cosines[i]), 1e-6), ref = double(f.p.reference[i]) + f.p.epsilon;
      for (std::size_t j = 0; j < f.c; ++j)
        y[Eigen::Index(j)] = std::max(0.0, (ref * std::exp(mapped_y[Eigen::Index(j)]) - f.p.epsilon) / cw);
      const Eigen::VectorXd s = f.hats * y;
      for (std::size_t band = 0; band < f.b; ++band)
        grid[band * brdf::kMerlCells + cells[i]] = float(s[Eigen::Index(band)]);
    }
  });
}

Fit check_fit(const BrdfPrior& p, const ComponentSource& components, const PriorObservations& obs,
              const PriorFitOptions& o, std::span<const float> grid) {
  Fit f{.p = p, .obs = obs, .k = p.k(), .c = p.channels(), .b = p.wavelengths.size(), .d = p.cells()};
  const std::size_t n = obs.cell.size();
  if (f.d != valid_cells().size() || p.reference.size() != f.d || !components)
    throw UsageError("prior: malformed prior (its sizes disagree, or no components)");
  if (grid.size() != f.b * brdf::kMerlCells || obs.values.size() != n * f.b || obs.weight.size() != n)
    throw UsageError("prior: observation or grid sizes do not match the prior's " + std::to_string(f.b) + " bands");
  if (n == 0) throw InputError("prior: no observation to fit");
  if (!(o.lambda >= 0) || !std::isfinite(o.lambda)) throw UsageError("prior: lambda must be finite and >= 0");
  for (const std::uint32_t i : obs.cell)
    if (i >= f.d) throw UsageError("prior: observation cell out of range");
  for (const float w : obs.weight)
    if (!(w >= 0) || !std::isfinite(w)) throw UsageError("prior: observation weights must be finite and >= 0");
  f.weight = observation_weights(p, obs, o);
  f.order.resize(n);
  for (std::size_t s = 0; s < n; ++s) f.order[s] = std::uint32_t(s);
  std::ranges::stable_sort(f.order, {}, [&](std::uint32_t s) { return obs.cell[s]; });
  f.hats = hat_basis(p.wavelengths, p.knots);
  f.proj = hat_projection(f.hats);
  return f;
}

}  // namespace

void fit_prior(const BrdfPrior& p, const ComponentSource& components, const PriorObservations& obs,
               const PriorFitOptions& o, std::span<float> grid, std::span<const std::uint32_t> at) {
  const Fit f = check_fit(p, components, obs, o, grid);
  for (std::size_t t = 0; t < at.size(); ++t)
    if (at[t] >= f.d || (t > 0 && at[t] <= at[t - 1]))
      throw UsageError("prior: the cells to write must ascend within the valid cells");
  const std::size_t block = prior_block_cells(o.block_bytes, 4 * std::max<std::size_t>(f.k, 1));
  Buffer<float> q;  // left unwritten until the components are read into it
  std::size_t loaded = std::size_t(-1);
  const auto load = [&](std::size_t i0, std::size_t count) {  // the components of the block of count cells from i0
    if (loaded == i0) return;
    check_interrupt();
    q.resize(f.k * count);
    components(i0, count, q);
    loaded = i0;
  };
  // Per channel: minimise sum_s w_s (mean_s + Q_s a - y_s)^2 + lambda sum_q a_q^2 / variance_q.
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(Eigen::Index(f.k), Eigen::Index(f.k));
  Eigen::MatrixXd atb = Eigen::MatrixXd::Zero(Eigen::Index(f.k), Eigen::Index(f.c));
  std::size_t next = 0;
  ScratchPool pool;
  std::vector<PieceSums> sums(kPiecesInFlight);
  Progress progress("fitting the prior", 2 * f.d);
  for (std::size_t i0 = 0; i0 < f.d; i0 += block) {
    const std::size_t count = std::min(block, f.d - i0);
    if (next < f.order.size() && obs.cell[f.order[next]] < i0 + count) {  // blocks without observations add nothing
      load(i0, count);
      add_equations(f, i0, count, q, next, pool, sums, ata, atb);
    }
    progress.advance(count);
  }
  for (std::size_t j = 0; j < f.k; ++j) ata(Eigen::Index(j), Eigen::Index(j)) += o.lambda / p.variances[j];
  const Eigen::MatrixXd a = ata.selfadjointView<Eigen::Lower>().ldlt().solve(atb);  // k x c; ata's lower half
  std::vector<std::uint32_t> cell;                                  // the block's cells written, from its first
  for (std::size_t i0 = (f.d - 1) / block * block;; i0 -= block) {  // backwards: the last block read is reused
    const std::size_t count = std::min(block, f.d - i0);
    cell.clear();
    if (at.empty()) {
      for (std::size_t t = 0; t < count; ++t) cell.push_back(std::uint32_t(t));
    } else {
      for (auto it = std::ranges::lower_bound(at, std::uint32_t(i0)); it != at.end() && *it < i0 + count; ++it)
        cell.push_back(std::uint32_t(*it - i0));
    }
    if (!cell.empty()) {
      load(i0, count);
      reconstruct(f, a, i0, count, cell, q, grid);
    }
    progress.advance(count);
    if (i0 == 0) break;
  }
}

void fit_prior(const BrdfPrior& p, const PriorObservations& obs, const PriorFitOptions& o, std::span<float> grid) {
  fit_prior(p, memory_components(p), obs, o, grid);
}

ComponentSource memory_components(const BrdfPrior& p) {
  if (p.components.size() != p.k() * p.cells())
    throw UsageError("prior: malformed prior (its components are not k x cells)");
  return [&p](std::size_t first, std::size_t count, std::span<float> out) {
    const std::size_t d = p.cells(), k = p.k();
    if (first > d || count > d - first || out.size() != k * count)
      throw UsageError("prior: component range or buffer size is wrong");
    for (std::size_t q = 0; q < k; ++q)
      std::copy_n(p.components.begin() + std::ptrdiff_t(q * d + first), count, out.begin() + std::ptrdiff_t(q * count));
  };
}

}  // namespace specula::acquire
