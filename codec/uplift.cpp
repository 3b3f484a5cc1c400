#include "specula/codec/uplift.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/text.h"

namespace specula::codec {

Uplift::Uplift(const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights, double alpha) : alpha_(alpha) {
  const Eigen::Index b = weights.cols();
  if (b < 3) throw UsageError("uplift: needs at least 3 bands, got " + std::to_string(b));
  if (!std::isfinite(alpha) || alpha < 0)
    throw UsageError("uplift: alpha is " + num(alpha) + "; it must be finite and >= 0");
  if (!weights.allFinite()) throw UsageError("uplift: the RGB weights hold non-finite values");
  system_ = Eigen::MatrixXd::Zero(3 + b - 2, b);
  system_.topRows(3) = weights;
  for (Eigen::Index r = 0; r + 2 < b; ++r) {
    system_(3 + r, r) = alpha;
    system_(3 + r, r + 1) = -2 * alpha;
    system_(3 + r, r + 2) = alpha;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(system_);
  if (qr.rank() < b)
    throw UsageError("uplift: eq A.3 is rank deficient (rank " + std::to_string(qr.rank()) + " of " +
                     std::to_string(b) + "); use alpha > 0 and RGB weights that are not all linear in wavelength");
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(system_.rows(), 3);
  rhs.topRows(3).setIdentity();
  solve_ = qr.solve(rhs);
  gram_ = system_.transpose() * system_;
  nnls_.emplace(gram_);
  at_ = weights.transpose();
}

void Uplift::solve(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x) const {
  if (x.size() != system_.cols())
    throw UsageError("uplift: output has " + std::to_string(x.size()) + " bands, expected " +
                     std::to_string(system_.cols()));
  x = solve_ * rgb;
}

bool Uplift::clamped(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x) const {
  solve(rgb, x);
  bool any = false;
  for (Eigen::Index k = 0; k < x.size(); ++k)
    if (x[k] < 0) {
      x[k] = 0;
      any = true;
    }
  return any;
}

bool Uplift::nonnegative(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x, UpliftCache* cache) const {
  solve(rgb, x);
  if (x.minCoeff() >= 0) return false;  // the unconstrained minimiser is feasible, so it is the bounded one
  const Eigen::VectorXd g = at_ * rgb;
  const Eigen::Index n = x.size();
  if (!cache || n > 64) {
    nnls_->solve(g.data(), x.data());
    return true;
  }
  // The optimum for a passive set P is linear in rgb; it is the bounded optimum when x >= 0 on P and the
  // gradient is <= 0 off P (KKT), with the solver's own tolerance.
  const Eigen::MatrixXd& gram = nnls_->gram();
  const double tol = nnls_->tolerance(g.data());
  const double neg = 1e-12 * std::max(1.0, x.cwiseAbs().maxCoeff());
  auto& entries = cache->entries_;
  for (std::size_t e = 0; e < entries.size(); ++e) {
    const UpliftCache::Entry& entry = entries[e];
    Eigen::VectorXd cand = entry.x * rgb;
    if (cand.minCoeff() < -neg) continue;
    const Eigen::VectorXd w = entry.w * rgb;
    bool optimal = true;
    for (Eigen::Index j = 0; j < n && optimal; ++j)
      if (!(entry.passive >> j & 1)) optimal = w[j] <= tol;
    if (!optimal) continue;
    x = cand.cwiseMax(0.0);
    std::rotate(entries.begin(), entries.begin() + std::ptrdiff_t(e), entries.begin() + std::ptrdiff_t(e) + 1);
    ++cache->hits_;
    return true;
  }
  ++cache->misses_;
  UpliftCache::Entry entry;
  entry.passive = entries.empty() ? 0 : entries.front().passive;  // a warm start: neighbours' sets are close
  nnls_->solve(g.data(), x.data(), entry.passive);
  std::vector<Eigen::Index> idx;
  for (Eigen::Index j = 0; j < n; ++j)
    if (entry.passive >> j & 1) idx.push_back(j);
  const auto k = Eigen::Index(idx.size());
  Eigen::MatrixXd gp(k, k);
  Eigen::Matrix<double, Eigen::Dynamic, 3> rp(k, 3);
  for (Eigen::Index a = 0; a < k; ++a) {
    rp.row(a) = at_.row(idx[std::size_t(a)]);
    for (Eigen::Index b = 0; b < k; ++b) gp(a, b) = gram(idx[std::size_t(a)], idx[std::size_t(b)]);
  }
  const Eigen::Matrix<double, Eigen::Dynamic, 3> sp = gp.ldlt().solve(rp);
  entry.x = Eigen::Matrix<double, Eigen::Dynamic, 3>::Zero(n, 3);
  for (Eigen::Index a = 0; a < k; ++a) entry.x.row(idx[std::size_t(a)]) = sp.row(a);
  // A coefficient-wise product: Eigen's blocked GEMM gave last-bit differences between thread counts here.
  entry.w = at_ - gram.lazyProduct(entry.x);
  constexpr std::size_t kEntries = 16;
  if (entries.size() == kEntries) entries.pop_back();
  entries.insert(entries.begin(), std::move(entry));
  return true;
}

store::Grid uplift_merl(const MerlBrdf& rgb, const WavelengthGrid& wavelengths, const Uplift& uplift,
                        UpliftMethod method, UpliftReport* report) {
  const std::size_t b = uplift.bands();
  if (wavelengths.size() != b)
    throw UsageError("uplift: " + std::to_string(wavelengths.size()) + " wavelengths for " + std::to_string(b) +
                     " bands");
  store::Grid grid;
  grid.wavelengths = wavelengths;
  grid.scale = 1.0;
  grid.units = "1/sr";
  grid.brdf.assign(b * brdf::kMerlCells, -1.0f);
  const Eigen::MatrixXd a = uplift.system().topRows(3);
  // One active-set cache per block of cells, not per thread: a cache hit agrees with a fresh solve only to
  // rounding, so the grid must not depend on which cells a thread happened to see before.
  constexpr std::size_t kBlock = 4096;
  struct BlockTally {
    std::size_t cells = 0, constrained = 0;
    double max_err = 0;
  };
  std::vector<BlockTally> tally((brdf::kMerlCells + kBlock - 1) / kBlock);
  parallel_for(tally.size(), [&](std::size_t blk) {
    Eigen::VectorXd x = Eigen::VectorXd::Zero(Eigen::Index(b));
    UpliftCache cache;
    BlockTally& t = tally[blk];
    for (std::size_t cell = blk * kBlock; cell < std::min(brdf::kMerlCells, (blk + 1) * kBlock); ++cell) {
      if (!rgb.has_data(cell)) continue;
      const Eigen::Vector3d v(rgb.value(0, cell), rgb.value(1, cell), rgb.value(2, cell));
      const bool changed = method == UpliftMethod::clamp ? uplift.clamped(v, x) : uplift.nonnegative(v, x, &cache);
      ++t.cells;
      t.constrained += changed;
      t.max_err = std::max(t.max_err, (a * x - v).cwiseAbs().maxCoeff() / std::max(v.cwiseAbs().maxCoeff(), 1e-300));
      for (std::size_t k = 0; k < b; ++k) grid.brdf[k * brdf::kMerlCells + cell] = float(x[Eigen::Index(k)]);
    }
  });
  std::size_t cells = 0, constrained = 0;
  double max_err = 0;
  for (const BlockTally& t : tally) {
    cells += t.cells;
    constrained += t.constrained;
    max_err = std::max(max_err, t.max_err);
  }
  if (report) *report = {cells, constrained, max_err};
  return grid;
}

std::size_t uplift_image(std::span<const float> rgb, std::size_t width, std::size_t height, const Uplift& uplift,
                         UpliftMethod method, std::span<float> out) {
  const std::size_t b = uplift.bands(), pixels = width * height;
  if (rgb.size() != 3 * pixels || out.size() != b * pixels)
    throw UsageError("uplift_image: a " + std::to_string(width) + " x " + std::to_string(height) + " image needs " +
                     std::to_string(3 * pixels) + " RGB values and " + std::to_string(b * pixels) + " outputs, got " +
                     std::to_string(rgb.size()) + " and " + std::to_string(out.size()));
  for (std::size_t i = 0; i < rgb.size(); ++i)
    if (rgb[i] < 0)
      throw InputError("pixel (" + std::to_string(i / 3 % width) + ", " + std::to_string(i / 3 / width) +
                       ") has a negative channel; radiance must be non-negative");
  // Per-row counts and caches: which pixels a cache answers depends only on the row, not on the thread.
  std::vector<std::size_t> constrained(height, 0);
  parallel_for(
      height, [&] { return Eigen::VectorXd(Eigen::Index(b)); },
      [&](std::size_t y, Eigen::VectorXd& x) {
        UpliftCache cache;
        for (std::size_t p = y * width; p < (y + 1) * width; ++p) {
          const Eigen::Vector3d c(rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]);
          constrained[y] +=
              method == UpliftMethod::nonnegative ? uplift.nonnegative(c, x, &cache) : uplift.clamped(c, x);
          for (std::size_t k = 0; k < b; ++k) out[p * b + k] = float(x[Eigen::Index(k)]);
        }
      });
  std::size_t total = 0;
  for (const std::size_t c : constrained) total += c;
  return total;
}

}  // namespace specula::codec
