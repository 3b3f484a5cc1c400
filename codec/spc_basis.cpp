// Spectral bases for .spc coding: a learned store basis orthonormalised, one fitted to the grid itself, and a
// learned basis extended by what it leaves of the grid.
#include <Eigen/QR>
#include <cmath>

#include "specula/codec/spc.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/eigenpairs.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {

using brdf::kMerlCells;
using brdf::kMerlThetaH;
namespace {
constexpr std::size_t kSlab = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;  // cells per theta_h index
}  // namespace

std::size_t coding_basis_max_k(const store::Basis& basis) {
  return std::min(basis.k() + (basis.method == "pca" ? 1 : 0), basis.bands());
}

SpcBasis coding_basis(const store::Basis& basis, std::size_t k, const std::string& reference) {
  const bool pca = basis.method == "pca";
  if (k < 1 || k > coding_basis_max_k(basis))
    throw UsageError("k = " + std::to_string(k) + ": basis " + reference + " gives 1 to " +
                     std::to_string(coding_basis_max_k(basis)) + " spectra" +
                     (pca ? " (its mean and components)" : ""));
  Eigen::MatrixXd m(Eigen::Index(basis.bands()), Eigen::Index(k));
  std::size_t col = 0;
  if (pca) m.col(Eigen::Index(col++)) = basis.mean;
  for (Eigen::Index j = 0; col < k; ++j) m.col(Eigen::Index(col++)) = basis.components.row(j).transpose();
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(m);
  const Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(m.rows(), m.cols());
  const Eigen::VectorXd diag = qr.matrixQR().diagonal();
  if (diag.cwiseAbs().minCoeff() <= 1e-10 * diag.cwiseAbs().maxCoeff())
    throw InputError(reference + ": its first " + std::to_string(k) +
                     " spectra are linearly dependent; use a smaller -k");
  return {basis.wavelengths, q.transpose(), reference};
}

namespace {
// Second moment of the grid's shapes r = x / mean(x) after removing their projection on `remove` (k x B, may
// be empty), over valid cells with a non-zero magnitude; the cell count in n.
Eigen::MatrixXd shape_moment(const store::Grid& grid, const Eigen::MatrixXd& remove, std::uint64_t& n) {
  const std::size_t b = grid.bands();
  if (grid.brdf.size() != b * kMerlCells) throw UsageError("basis fit: grid values do not match bands x 90 x 90 x 180");
  std::vector<Eigen::MatrixXd> part(kMerlThetaH, Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(b)));
  std::vector<std::uint64_t> count(kMerlThetaH, 0);
  parallel_for(
      std::size_t(kMerlThetaH), [&] { return Eigen::VectorXd(static_cast<Eigen::Index>(b)); },
      [&](std::size_t h, Eigen::VectorXd& r) {
        for (std::size_t c = h * kSlab; c < (h + 1) * kSlab; ++c) {
          double m = 0;
          bool valid = true;
          for (std::size_t j = 0; j < b; ++j) {
            const float v = grid.brdf[j * kMerlCells + c];
            valid &= v >= 0;
            r[Eigen::Index(j)] = v;
            m += v;
          }
          if (!valid || !(m > 0) || !std::isfinite(m)) continue;
          r *= double(b) / m;
          if (remove.rows() > 0) r -= remove.transpose() * (remove * r);
          part[h].selfadjointView<Eigen::Lower>().rankUpdate(r);
          ++count[h];
        }
      });
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(b));
  n = 0;
  for (int h = 0; h < kMerlThetaH; ++h) g += part[std::size_t(h)], n += count[std::size_t(h)];
  g.triangularView<Eigen::StrictlyUpper>() = g.transpose();
  return g;
}

// The top k eigenvectors of symmetric g as rows, each with its largest entry positive.
Eigen::MatrixXd top_rows(const Eigen::MatrixXd& g, std::size_t k) {
  return symmetric_eigenpairs(g, k).vectors.transpose();
}
}  // namespace

SpcBasis self_basis(const store::Grid& grid, std::size_t k) {
  const std::size_t b = grid.bands();
  if (k < 1 || k > b)
    throw UsageError("k = " + std::to_string(k) + ": give 1 to " + std::to_string(b) + " for a self basis");
  std::uint64_t n = 0;
  const Eigen::MatrixXd g = shape_moment(grid, Eigen::MatrixXd(0, Eigen::Index(b)), n);
  if (n == 0) throw InputError("the grid has no valid cell with a non-zero spectrum to fit a basis to");
  return {grid.wavelengths, top_rows(g, k), "self"};
}

SpcBasis self_basis(const SpcSampleSet& samples, std::size_t k) {
  const std::size_t b = samples.wavelengths.size(), n = samples.size();
  if (k < 1 || k > b)
    throw UsageError("k = " + std::to_string(k) + ": give 1 to " + std::to_string(b) + " for a self basis");
  if (samples.values.size() != n * b) throw UsageError("basis fit: sample values do not match samples x bands");
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(Eigen::Index(b), Eigen::Index(b));
  Eigen::VectorXd r(static_cast<Eigen::Index>(b));
  std::size_t used = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double m = 0;
    for (std::size_t j = 0; j < b; ++j) m += (r[Eigen::Index(j)] = samples.values[i * b + j]);
    if (!(m > 0) || !std::isfinite(m)) continue;
    r *= double(b) / m;
    g.selfadjointView<Eigen::Lower>().rankUpdate(r);
    ++used;
  }
  if (used == 0) throw InputError("the samples have no spectrum of positive mean to fit a basis to");
  g.triangularView<Eigen::StrictlyUpper>() = g.transpose();
  return {samples.wavelengths, top_rows(g, k), "self"};
}

SpcBasis augment_basis(const SpcBasis& basis, const store::Grid& grid, std::size_t extra) {
  const std::size_t b = grid.bands();
  if (basis.rows.cols() != Eigen::Index(b) || !basis.wavelengths.approx_equal(grid.wavelengths))
    throw InputError("the grid has " + grid.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code a grid with a basis on its own wavelengths");
  if (basis.k() + extra > b)
    throw UsageError("extra = " + std::to_string(extra) + ": with k = " + std::to_string(basis.k()) + " at most " +
                     std::to_string(b - basis.k()) + " more spectra fit in " + std::to_string(b) + " bands");
  if (extra == 0) return basis;
  std::uint64_t n = 0;
  const Eigen::MatrixXd g = shape_moment(grid, basis.rows, n);
  if (n == 0) throw InputError("the grid has no valid cell with a non-zero spectrum to fit a basis to");
  SpcBasis out = basis;
  out.rows.conservativeResize(Eigen::Index(basis.k() + extra), Eigen::NoChange);
  out.rows.bottomRows(Eigen::Index(extra)) = top_rows(g, extra);
  // Re-orthonormalise against rounding (the new rows are orthogonal to the old in exact arithmetic).
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(out.rows.transpose());
  Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(Eigen::Index(b), out.rows.rows());
  for (Eigen::Index j = 0; j < q.cols(); ++j)
    if (q.col(j).dot(out.rows.row(j).transpose()) < 0) q.col(j) = -q.col(j);
  out.rows = q.transpose();
  out.reference = basis.reference + "+" + std::to_string(extra);
  return out;
}

}  // namespace specula::codec
