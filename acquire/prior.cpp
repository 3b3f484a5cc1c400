#include "specula/acquire/prior.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kBlock = 8192;  // cells per parallel work item

Eigen::MatrixXd projection(const Eigen::MatrixXd& hats) {  // C x B least-squares projection onto the hats
  return (hats.transpose() * hats).ldlt().solve(hats.transpose());
}

std::vector<double> even_knots(const WavelengthGrid& w, std::size_t c) {
  std::vector<double> k(c);
  for (std::size_t j = 0; j < c; ++j) k[j] = w[0] + (w[w.size() - 1] - w[0]) * double(j) / double(c - 1);
  return k;
}

// ln((x + eps) / (ref + eps)) of cos-weighted values x, ref.
inline float mapped(float x, float ref, double eps) { return float(std::log((double(x) + eps) / (double(ref) + eps))); }

}  // namespace

const std::vector<std::uint32_t>& valid_cells() {
  static const std::vector<std::uint32_t> cells = [] {
    std::vector<std::uint32_t> v;
    for (std::size_t i = 0; i < brdf::kMerlCells; ++i)
      if (brdf::merl_cell_valid(brdf::merl_cell(i))) v.push_back(std::uint32_t(i));
    return v;
  }();
  return cells;
}

const std::vector<float>& valid_cell_cosines() {
  static const std::vector<float> cosines = [] {
    const auto& cells = valid_cells();
    std::vector<float> c(cells.size());
    for (std::size_t d = 0; d < cells.size(); ++d) {
      Eigen::Vector3d wi, wo;
      brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cells[d])), wi, wo);
      c[d] = float(wi.z() * wo.z());
    }
    return c;
  }();
  return cosines;
}

Eigen::MatrixXd hat_basis(const WavelengthGrid& wavelengths, std::span<const double> knots) {
  const Eigen::Index b = Eigen::Index(wavelengths.size()), c = Eigen::Index(knots.size());
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(b, c);
  for (Eigen::Index i = 0; i < b; ++i) {
    const double x = wavelengths[std::size_t(i)];
    if (x <= knots.front()) {
      h(i, 0) = 1;
      continue;
    }
    if (x >= knots.back()) {
      h(i, c - 1) = 1;
      continue;
    }
    std::size_t j = 0;
    while (knots[j + 1] < x) ++j;
    const double t = (x - knots[j]) / (knots[j + 1] - knots[j]);
    h(i, Eigen::Index(j)) = 1 - t;
    h(i, Eigen::Index(j + 1)) = t;
  }
  return h;
}

BrdfPrior build_prior(std::size_t count, const std::function<store::Grid(std::size_t)>& load,
                      std::span<const std::string> names, const PriorOptions& o) {
  if (count < 2 || names.size() != count) throw UsageError("prior: give at least 2 training grids, each named");
  if (o.channels < 2 || o.channels > 64) throw UsageError("prior: channels must be 2 to 64");
  if (!(o.epsilon > 0) || !std::isfinite(o.epsilon)) throw UsageError("prior: epsilon must be positive and finite");
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  const std::size_t d = cells.size(), c = o.channels, m = count * c;
  BrdfPrior p;
  p.epsilon = o.epsilon;
  p.training.assign(names.begin(), names.end());
  Eigen::MatrixXf x(static_cast<Eigen::Index>(d),
                    static_cast<Eigen::Index>(m));  // cos-weighted channel values, then mapped
  Eigen::MatrixXd proj;
  for (std::size_t g = 0; g < count; ++g) {
    const store::Grid grid = load(g);
    const std::size_t b = grid.bands();
    if (g == 0) {
      if (b < c)
        throw InputError("prior: grid '" + names[0] + "' has " + std::to_string(b) + " bands, fewer than the " +
                         std::to_string(c) + " channels asked for");
      p.wavelengths = grid.wavelengths;
      p.knots = even_knots(grid.wavelengths, c);
      proj = projection(hat_basis(p.wavelengths, p.knots));
    } else if (!std::ranges::equal(grid.wavelengths.values(), p.wavelengths.values())) {
      throw InputError("prior: grid '" + names[g] + "' has bands " + grid.wavelengths.describe() + ", not the " +
                       p.wavelengths.describe() + " of '" + names[0] + "'; uplift or resample it to those bands");
    }
    if (grid.brdf.size() != b * brdf::kMerlCells) throw UsageError("prior: grid '" + names[g] + "' has the wrong size");
    std::vector<std::size_t> holes((d + kBlock - 1) / kBlock, 0);
    parallel_for(holes.size(), [&](std::size_t blk) {
      Eigen::VectorXd s(static_cast<Eigen::Index>(b));
      for (std::size_t i = blk * kBlock; i < std::min(d, (blk + 1) * kBlock); ++i) {
        bool hole = false;
        for (std::size_t k = 0; k < b; ++k) {
          const float v = grid.brdf[k * brdf::kMerlCells + cells[i]];
          hole |= !(v >= 0) || !std::isfinite(v);
          s[Eigen::Index(k)] = double(v) * grid.scale;
        }
        holes[blk] += hole;
        const Eigen::VectorXd ch = (proj * s).cwiseMax(0.0) * double(cosines[i]);
        for (std::size_t j = 0; j < c; ++j) x(Eigen::Index(i), Eigen::Index(g * c + j)) = float(ch[Eigen::Index(j)]);
      }
    });
    std::size_t missing = 0;
    for (const std::size_t h : holes) missing += h;
    if (missing)
      throw InputError("prior: grid '" + names[g] + "' has no data (or a non-finite value) at " +
                       std::to_string(missing) + " of the " + std::to_string(d) +
                       " valid cells; a prior learns from complete grids");
  }
  // The reference: per cell the median over observations; then every value mapped and centred.
  p.reference.resize(d);
  p.mean.resize(d);
  parallel_for((d + kBlock - 1) / kBlock, [&](std::size_t blk) {
    std::vector<float> row(m);
    for (std::size_t i = blk * kBlock; i < std::min(d, (blk + 1) * kBlock); ++i) {
      for (std::size_t j = 0; j < m; ++j) row[j] = x(Eigen::Index(i), Eigen::Index(j));
      std::nth_element(row.begin(), row.begin() + std::ptrdiff_t(m / 2), row.end());
      const float ref = row[m / 2];
      p.reference[i] = ref;
      double sum = 0;
      for (std::size_t j = 0; j < m; ++j) {
        const float y = mapped(x(Eigen::Index(i), Eigen::Index(j)), ref, o.epsilon);
        x(Eigen::Index(i), Eigen::Index(j)) = y;
        sum += y;
      }
      p.mean[i] = float(sum / double(m));
      for (std::size_t j = 0; j < m; ++j) x(Eigen::Index(i), Eigen::Index(j)) -= p.mean[i];
    }
  });
  // PCA through the m x m Gram matrix of the centred observations (m << cells), summed by blocks in order.
  const std::size_t blocks = (d + kBlock - 1) / kBlock;
  std::vector<Eigen::MatrixXd> partial(blocks);
  parallel_for(blocks, [&](std::size_t blk) {
    const Eigen::Index i0 = Eigen::Index(blk * kBlock), n = Eigen::Index(std::min(d, (blk + 1) * kBlock)) - i0;
    const Eigen::MatrixXd xb = x.middleRows(i0, n).cast<double>();
    partial[blk] = xb.transpose() * xb;
  });
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(Eigen::Index(m), Eigen::Index(m));
  for (const auto& g : partial) gram += g;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  std::size_t k = o.components ? std::min(o.components, m - 1) : m - 1;
  const double top = eig.eigenvalues()[Eigen::Index(m) - 1];
  while (k > 0 && !(eig.eigenvalues()[Eigen::Index(m - k)] > 1e-12 * top)) --k;  // drop null directions
  p.variances.resize(k);
  p.components.assign(k * d, 0.0f);
  for (std::size_t q = 0; q < k; ++q) {
    const Eigen::Index col = Eigen::Index(m - 1 - q);
    const double lambda = eig.eigenvalues()[col];
    p.variances[q] = lambda / double(m - 1);
    const Eigen::VectorXd v = eig.eigenvectors().col(col) / std::sqrt(lambda);
    parallel_for(blocks, [&](std::size_t blk) {
      for (std::size_t i = blk * kBlock; i < std::min(d, (blk + 1) * kBlock); ++i)
        p.components[q * d + i] = float(x.row(Eigen::Index(i)).cast<double>().dot(v));
    });
  }
  return p;
}

void fit_prior(const BrdfPrior& p, const PriorObservations& obs, const PriorFitOptions& o, std::span<float> grid) {
  const std::size_t d = p.cells(), k = p.k(), c = p.channels(), b = p.wavelengths.size(), n = obs.cell.size();
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  if (d != cells.size() || p.components.size() != k * d || p.reference.size() != d)
    throw UsageError("prior: malformed prior (its sizes disagree)");
  if (grid.size() != b * brdf::kMerlCells || obs.values.size() != n * b || obs.weight.size() != n)
    throw UsageError("prior: observation or grid sizes do not match the prior's " + std::to_string(b) + " bands");
  if (n == 0) throw InputError("prior: no observation to fit");
  if (!(o.lambda >= 0) || !std::isfinite(o.lambda)) throw UsageError("prior: lambda must be finite and >= 0");
  const Eigen::MatrixXd hats = hat_basis(p.wavelengths, p.knots);
  const Eigen::MatrixXd proj = projection(hats);
  // Per channel: minimise sum_s w_s (mean_s + Q_s a - y_s)^2 + lambda sum_q a_q^2 / variance_q.
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(Eigen::Index(k), Eigen::Index(k));
  Eigen::MatrixXd atb = Eigen::MatrixXd::Zero(Eigen::Index(k), Eigen::Index(c));
  Eigen::VectorXd q(static_cast<Eigen::Index>(k));
  for (std::size_t s = 0; s < n; ++s) {
    const std::size_t i = obs.cell[s];
    if (i >= d) throw UsageError("prior: observation cell out of range");
    const Eigen::Map<const Eigen::VectorXf> spec(&obs.values[s * b], Eigen::Index(b));
    const Eigen::VectorXd ch = (proj * spec.cast<double>()).cwiseMax(0.0) * double(cosines[i]);
    for (std::size_t j = 0; j < k; ++j) q[Eigen::Index(j)] = p.components[j * d + i];
    const double w = obs.weight[s];
    ata.noalias() += w * q * q.transpose();
    for (std::size_t j = 0; j < c; ++j)
      atb.col(Eigen::Index(j)) +=
          w * (double(mapped(float(ch[Eigen::Index(j)]), p.reference[i], p.epsilon)) - p.mean[i]) * q;
  }
  for (std::size_t j = 0; j < k; ++j) ata(Eigen::Index(j), Eigen::Index(j)) += o.lambda / p.variances[j];
  const Eigen::MatrixXd a = ata.ldlt().solve(atb);  // k x c
  parallel_for((d + kBlock - 1) / kBlock, [&](std::size_t blk) {
    Eigen::VectorXd y(static_cast<Eigen::Index>(c)), qi(static_cast<Eigen::Index>(k));
    for (std::size_t i = blk * kBlock; i < std::min(d, (blk + 1) * kBlock); ++i) {
      for (std::size_t j = 0; j < k; ++j) qi[Eigen::Index(j)] = p.components[j * d + i];
      const Eigen::VectorXd mapped_y = (a.transpose() * qi).array() + double(p.mean[i]);
      const double cw = std::max(double(cosines[i]), 1e-6), ref = double(p.reference[i]) + p.epsilon;
      for (std::size_t j = 0; j < c; ++j)
        y[Eigen::Index(j)] = std::max(0.0, (ref * std::exp(mapped_y[Eigen::Index(j)]) - p.epsilon) / cw);
      const Eigen::VectorXd s = hats * y;
      for (std::size_t band = 0; band < b; ++band)
        grid[band * brdf::kMerlCells + cells[i]] = float(s[Eigen::Index(band)]);
    }
  });
}

}  // namespace specula::acquire
