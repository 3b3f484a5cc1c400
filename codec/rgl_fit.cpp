#include "specula/codec/rgl_fit.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>

#include "specula/codec/rgl_eval.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

// The cells are summed in this many blocks of theta_h rows, each on one thread, added in order.
constexpr std::size_t kBlocks = 6;
// Unknowns couple only with their neighbours in (theta_i, row, column): a 3 x 3 x 3 stencil.
constexpr std::size_t kSlots = 27;

struct Layout {
  std::size_t T, R, C;
  std::size_t unknowns() const { return T * R * R; }
  // Slot of unknown q in the band of unknown p (both from one stencil, so neighbours).
  std::size_t slot(std::size_t p, std::size_t q) const {
    const long dt = long(q / (R * R)) - long(p / (R * R)), dj = long(q % (R * R) / R) - long(p % (R * R) / R),
               di = long(q % R) - long(p % R);
    return std::size_t((dt + 1) * 9 + (dj + 1) * 3 + (di + 1));
  }
  std::size_t neighbour(std::size_t p, std::size_t slot) const {  // kSlots if outside
    const long t = long(p / (R * R)) + long(slot / 9) - 1, j = long(p % (R * R) / R) + long(slot / 3 % 3) - 1,
               i = long(p % R) + long(slot % 3) - 1;
    if (t < 0 || j < 0 || i < 0 || t >= long(T) || j >= long(R) || i >= long(R)) return unknowns();
    return std::size_t(t) * R * R + std::size_t(j) * R + std::size_t(i);
  }
};

// The normal equations of one block: per unknown its kSlots band entries, and per unknown and channel the
// right-hand side.
struct Normal {
  std::vector<double> band, rhs;
};

// Luminance of every cell with data in all channels (negative otherwise), and the median over those.
std::vector<double> cell_luminance(std::span<const float> merl, std::size_t C, double scale,
                                   std::span<const double> lum, double& median) {
  std::vector<double> y(brdf::kMerlCells, -1.0);
  parallel_for(
      brdf::kMerlCells,
      [&](std::size_t cell) {
        double s = 0;
        for (std::size_t c = 0; c < C; ++c) {
          const float v = merl[c * brdf::kMerlCells + cell];
          if (!(v >= 0)) return;
          s += lum[c] * double(v) * scale;
        }
        if (brdf::merl_cell_valid(brdf::merl_cell(cell))) y[cell] = std::max(s, 0.0);
      },
      4096);
  std::vector<double> have;
  for (const double v : y)
    if (v >= 0) have.push_back(v);
  if (have.empty()) throw UsageError("rgl_fit_values: no cell above the horizon holds data");
  auto mid = have.begin() + std::ptrdiff_t(have.size() / 2);
  std::nth_element(have.begin(), mid, have.end());
  median = *mid;
  return y;
}

void accumulate(const RglEvaluator& e, const Layout& L, std::span<const float> merl, double scale,
                std::span<const double> y, double y_floor, const RglFitSettings& s, std::size_t h0, std::size_t h1,
                Normal& out) {
  const std::size_t per_h = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD, R2 = L.R * L.R;
  out.band.assign(L.unknowns() * kSlots, 0.0);
  out.rhs.assign(L.unknowns() * L.C, 0.0);
  std::vector<double> g(L.C);
  for (std::size_t cell = h0 * per_h; cell < h1 * per_h; ++cell) {
    if (!(y[cell] >= 0)) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
    const double rel = std::max(y[cell], y_floor);
    const double weight = std::pow(std::max(wi.z() * wo.z(), 0.0), s.cosine_power) / (rel * rel);
    for (std::size_t c = 0; c < L.C; ++c) g[c] = double(merl[c * brdf::kMerlCells + cell]) * scale;
    for (int order = 0; order < 2; ++order) {
      const RglStencil st = order == 0 ? e.stencil(wi, wo) : e.stencil(wo, wi);
      for (int k = 0; k < st.n; ++k) {
        const std::size_t p = st.theta[std::size_t(k)] * R2 + st.node[std::size_t(k)];
        const double wk = weight * st.weight[std::size_t(k)];
        for (int l = 0; l < st.n; ++l) {
          const std::size_t q = st.theta[std::size_t(l)] * R2 + st.node[std::size_t(l)];
          out.band[p * kSlots + L.slot(p, q)] += wk * st.weight[std::size_t(l)];
        }
        for (std::size_t c = 0; c < L.C; ++c) out.rhs[p * L.C + c] += wk * g[c];
      }
    }
  }
}

}  // namespace

void rgl_fit_values(RglBsdf& b, std::span<const float> merl, double scale, std::span<const double> lum_weights,
                    const RglFitSettings& s) {
  const Layout L{b.theta_i.size(), b.resolution, b.channels()};
  const std::size_t P = L.unknowns(), R2 = L.R * L.R;
  if (merl.size() != L.C * brdf::kMerlCells || lum_weights.size() != L.C || b.values.size() != P * L.C)
    throw UsageError("rgl_fit_values: the BRDF, the luminance weights and the material disagree in size");
  if (!(s.floor > 0) || !(s.prior > 0)) throw UsageError("rgl_fit_values: floor and prior must be positive");
  double median = 0;
  const std::vector<double> y = cell_luminance(merl, L.C, scale, lum_weights, median);
  const RglEvaluator e(b);
  std::vector<Normal> blocks(kBlocks);
  parallel_for(kBlocks, [&](std::size_t k) {
    accumulate(e, L, merl, scale, y, s.floor * median, s, k * brdf::kMerlThetaH / kBlocks,
               (k + 1) * brdf::kMerlThetaH / kBlocks, blocks[k]);
  });
  Normal& sum = blocks[0];
  for (std::size_t k = 1; k < kBlocks; ++k) {
    for (std::size_t i = 0; i < sum.band.size(); ++i) sum.band[i] += blocks[k].band[i];
    for (std::size_t i = 0; i < sum.rhs.size(); ++i) sum.rhs[i] += blocks[k].rhs[i];
    blocks[k] = {};
  }
  double diag = 0;
  for (std::size_t p = 0; p < P; ++p) diag += sum.band[p * kSlots + 13];
  const double lambda = s.prior * std::max(diag / double(P), 1e-300);
  std::vector<Eigen::Triplet<double>> triplets;
  for (std::size_t p = 0; p < P; ++p)
    for (std::size_t k = 0; k < kSlots; ++k) {
      const double v = sum.band[p * kSlots + k] + (k == 13 ? lambda : 0.0);
      const std::size_t q = L.neighbour(p, k);
      if (v != 0 && q < P) triplets.emplace_back(int(p), int(q), v);
    }
  Eigen::SparseMatrix<double> A{Eigen::Index(P), Eigen::Index(P)};
  A.setFromTriplets(triplets.begin(), triplets.end());
  A.makeCompressed();
  // Conjugate gradients from the starting values, per channel (independent: parallel, the same for any thread count);
  // a sparse factorisation of the 3 x 3 x 3 stencil fills in too much at the larger resolutions.
  parallel_for(L.C, [&](std::size_t c) {
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg(A);
    cg.setTolerance(s.tolerance);
    cg.setMaxIterations(Eigen::Index(s.max_iterations));
    Eigen::VectorXd rhs(P), x0(P);
    for (std::size_t p = 0; p < P; ++p) {
      x0[Eigen::Index(p)] = double(b.values[(p / R2 * L.C + c) * R2 + p % R2]);
      rhs[Eigen::Index(p)] = sum.rhs[p * L.C + c] + lambda * x0[Eigen::Index(p)];
    }
    const Eigen::VectorXd x = cg.solveWithGuess(rhs, x0);
    for (std::size_t p = 0; p < P; ++p)
      b.values[(p / R2 * L.C + c) * R2 + p % R2] = float(std::max(x[Eigen::Index(p)], 0.0));
  });
}

}  // namespace specula::codec
