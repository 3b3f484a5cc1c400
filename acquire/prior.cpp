#include "specula/acquire/prior.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "specula/acquire/retro_rise.h"
#include "specula/acquire/retro_trend.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/merl_cells.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/store/grid_rows.h"
#include "specula/store/prior.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kBlock = 8192;  // cells per parallel work item

std::vector<double> even_knots(const WavelengthGrid& w, std::size_t c) {
  std::vector<double> k(c);
  for (std::size_t j = 0; j < c; ++j) k[j] = w[0] + (w[w.size() - 1] - w[0]) * double(j) / double(c - 1);
  return k;
}

}  // namespace

const std::vector<std::uint32_t>& valid_cells() { return brdf::merl_valid_cells(); }

Eigen::MatrixXd hat_projection(const Eigen::MatrixXd& hats) {
  return (hats.transpose() * hats).ldlt().solve(hats.transpose());
}

std::size_t prior_block_cells(std::size_t bytes, std::size_t cell_bytes) {
  return store::kPriorBlockCells * std::max<std::size_t>(1, bytes / (cell_bytes * store::kPriorBlockCells));
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

namespace {

constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;  // cells per theta_h row

// What both passes share: the grids, the projection onto the channels and the block partition.
struct Training {
  std::span<const TrainingGrid> grids;
  std::size_t c = 0, m = 0, block = 0;
  Eigen::MatrixXd proj;
};

// The retro band's tallies of the first pass: the exponents' (over channel values) and the rise's (over bands).
struct RetroTallies {
  RetroExponentTally exponents;
  RetroRiseTally rise;
  std::size_t tallied = 0;  // theta_h rows [0, tallied) added
};

// Adds theta_h rows [tallied, h0 + rows) of grid g's block buf (bands x rows x kRow, rows from h0) to the tallies: the
// exponents' as channel values (the projection of each cell's spectrum) at the theta_d rows they read.
void tally_rows(const Training& t, std::size_t g, std::span<const float> buf, std::size_t h0, std::size_t rows,
                RetroTallies& tally) {
  const TrainingGrid& grid = t.grids[g];
  const std::size_t first = tally.tallied;
  if (first >= h0 + rows) return;
  const std::size_t b = grid.wavelengths.size(), n = h0 + rows - first, near = 2 * kRetroLearnedRows * brdf::kMerlPhiD;
  tally.rise.add(g, buf, b, h0, rows, first, grid.scale);
  std::vector<float> ch(t.c * n * kRow, 0.0f);
  parallel_for(n, [&](std::size_t i) {
    Eigen::VectorXd s(static_cast<Eigen::Index>(b));
    for (std::size_t at = 0; at < near; ++at) {
      for (std::size_t k = 0; k < b; ++k) s[Eigen::Index(k)] = double(buf[(k * rows + first - h0 + i) * kRow + at]);
      const Eigen::VectorXd c = t.proj * s * grid.scale;
      for (std::size_t j = 0; j < t.c; ++j) ch[(j * n + i) * kRow + at] = float(c[Eigen::Index(j)]);
    }
  });
  tally.exponents.add(ch, t.c, first, n);
}

// Cos-weighted channel values of cells [i0, i0 + n) of every grid into x (n x m, column g * c + j); counts each
// grid's cells without data into holes. With tallies, the theta_h rows from their tallied on are added to them (and
// tallied moved past the block's rows).
void read_block(const Training& t, std::size_t i0, std::size_t n, Eigen::MatrixXf& x, std::vector<std::size_t>& holes,
                RetroTallies* tally = nullptr) {
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  const std::size_t h0 = cells[i0] / kRow, rows = cells[i0 + n - 1] / kRow - h0 + 1;
  x.resize(Eigen::Index(n), Eigen::Index(t.m));
  std::vector<float> buf;
  for (std::size_t g = 0; g < t.grids.size(); ++g) {
    const TrainingGrid& grid = t.grids[g];
    const std::size_t b = grid.wavelengths.size();
    buf.resize(b * rows * kRow);
    grid.read_rows(h0, rows, buf);
    std::vector<std::size_t> missing((n + kBlock - 1) / kBlock, 0);
    parallel_for(missing.size(), [&](std::size_t blk) {
      Eigen::VectorXd s(static_cast<Eigen::Index>(b));
      for (std::size_t i = blk * kBlock; i < std::min(n, (blk + 1) * kBlock); ++i) {
        const std::size_t at = cells[i0 + i] - h0 * kRow;
        bool hole = false;
        for (std::size_t k = 0; k < b; ++k) {
          const float v = buf[k * rows * kRow + at];
          hole |= !(v >= 0) || !std::isfinite(v);
          s[Eigen::Index(k)] = double(v) * grid.scale;
        }
        missing[blk] += hole;
        const Eigen::VectorXd ch = (t.proj * s).cwiseMax(0.0) * double(cosines[i0 + i]);
        for (std::size_t j = 0; j < t.c; ++j)
          x(Eigen::Index(i), Eigen::Index(g * t.c + j)) = float(ch[Eigen::Index(j)]);
      }
    });
    for (const std::size_t h : missing) holes[g] += h;
    if (tally) tally_rows(t, g, buf, h0, rows, *tally);
  }
  if (tally) tally->tallied = h0 + rows;
}

// Maps x (cells [i0, i0 + n)) log-relatively to reference and centres it on mean.
void map_block(Eigen::MatrixXf& x, std::size_t i0, std::span<const float> reference, std::span<const float> mean,
               double eps) {
  const std::size_t n = std::size_t(x.rows()), m = std::size_t(x.cols());
  parallel_for((n + kBlock - 1) / kBlock, [&](std::size_t blk) {
    for (std::size_t i = blk * kBlock; i < std::min(n, (blk + 1) * kBlock); ++i)
      for (std::size_t j = 0; j < m; ++j) {
        float& v = x(Eigen::Index(i), Eigen::Index(j));
        v = prior_mapped(v, reference[i0 + i], eps) - mean[i0 + i];
      }
  });
}

// Per cell of x (cells [i0, i0 + n)): the median over observations as reference, the mean mapped value, the
// largest observation as ceiling.
void reference_and_mean(const Eigen::MatrixXf& x, std::size_t i0, double eps, BrdfPrior& p) {
  const std::size_t n = std::size_t(x.rows()), m = std::size_t(x.cols());
  parallel_for((n + kBlock - 1) / kBlock, [&](std::size_t blk) {
    std::vector<float> row(m);
    for (std::size_t i = blk * kBlock; i < std::min(n, (blk + 1) * kBlock); ++i) {
      for (std::size_t j = 0; j < m; ++j) row[j] = x(Eigen::Index(i), Eigen::Index(j));
      p.ceiling[i0 + i] = *std::ranges::max_element(row);
      std::nth_element(row.begin(), row.begin() + std::ptrdiff_t(m / 2), row.end());
      const float ref = row[m / 2];
      double sum = 0;
      for (std::size_t j = 0; j < m; ++j) sum += prior_mapped(x(Eigen::Index(i), Eigen::Index(j)), ref, eps);
      p.reference[i0 + i] = ref;
      p.mean[i0 + i] = float(sum / double(m));
    }
  });
}

Training check_training(std::span<const TrainingGrid> grids, const PriorOptions& o, BrdfPrior& p) {
  if (grids.size() < 2) throw UsageError("prior: give at least 2 training grids");
  if (o.channels < 2 || o.channels > 64) throw UsageError("prior: channels must be 2 to 64");
  if (!(o.epsilon > 0) || !std::isfinite(o.epsilon)) throw UsageError("prior: epsilon must be positive and finite");
  Training t{.grids = grids, .c = o.channels, .m = grids.size() * o.channels};
  p.epsilon = o.epsilon;
  p.wavelengths = grids[0].wavelengths;
  for (const auto& g : grids) {
    p.training.push_back(g.name);
    if (!std::ranges::equal(g.wavelengths.values(), p.wavelengths.values()))
      throw InputError("prior: grid '" + g.name + "' has bands " + g.wavelengths.describe() + ", not the " +
                       p.wavelengths.describe() + " of '" + grids[0].name + "'; uplift or resample it to those bands");
    if (!(g.scale > 0) || !std::isfinite(g.scale) || !g.read_rows)
      throw UsageError("prior: grid '" + g.name + "' has no rows to read or a bad scale");
  }
  if (p.wavelengths.size() < t.c)
    throw InputError("prior: grid '" + grids[0].name + "' has " + std::to_string(p.wavelengths.size()) +
                     " bands, fewer than the " + std::to_string(t.c) + " channels asked for");
  p.knots = even_knots(p.wavelengths, t.c);
  t.proj = hat_projection(hat_basis(p.wavelengths, p.knots));
  t.block = prior_block_cells(o.block_bytes, 4 * t.m);
  return t;
}

// Pass 1: reference, mean and the Gram matrix of the centred observations, summed over kBlock cells in cell order
// (the same sums for any thread count and block size); the retro band's exponents and rise maps.
Eigen::MatrixXd first_pass(const Training& t, BrdfPrior& p) {
  const std::size_t d = valid_cells().size();
  p.reference.resize(d);
  p.mean.resize(d);
  p.ceiling.resize(d);
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(Eigen::Index(t.m), Eigen::Index(t.m));
  std::vector<std::size_t> holes(t.grids.size(), 0);
  Eigen::MatrixXf x;
  RetroTallies tally{.rise = RetroRiseTally(t.grids.size())};
  for (std::size_t i0 = 0; i0 < d; i0 += t.block) {
    check_interrupt();
    const std::size_t n = std::min(t.block, d - i0);
    read_block(t, i0, n, x, holes, &tally);
    reference_and_mean(x, i0, p.epsilon, p);
    map_block(x, i0, p.reference, p.mean, p.epsilon);
    std::vector<Eigen::MatrixXd> partial((n + kBlock - 1) / kBlock);
    parallel_for(partial.size(), [&](std::size_t blk) {
      const Eigen::Index a = Eigen::Index(blk * kBlock), rows = Eigen::Index(std::min(n, (blk + 1) * kBlock)) - a;
      const Eigen::MatrixXd xb = x.middleRows(a, rows).cast<double>();
      partial[blk] = xb.transpose() * xb;
    });
    for (const auto& g : partial) gram += g;
  }
  for (std::size_t g = 0; g < t.grids.size(); ++g)
    if (holes[g])
      throw InputError("prior: grid '" + t.grids[g].name + "' has no data (or a non-finite value) at " +
                       std::to_string(holes[g]) + " of the " + std::to_string(d) +
                       " valid cells; a prior learns from complete grids");
  p.retro_exponents = tally.exponents.exponents();
  p.retro_rise = tally.rise.maps();
  return gram;
}

// The leading eigenvectors of gram scaled by 1 / sqrt(eigenvalue) (m x k); the variances into p.
Eigen::MatrixXd solve_components(const Eigen::MatrixXd& gram, std::size_t wanted, BrdfPrior& p) {
  const std::size_t m = std::size_t(gram.rows());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  std::size_t k = wanted ? std::min(wanted, m - 1) : m - 1;
  const double top = eig.eigenvalues()[Eigen::Index(m) - 1];
  while (k > 0 && !(eig.eigenvalues()[Eigen::Index(m - k)] > 1e-12 * top)) --k;  // drop null directions
  p.variances.resize(k);
  Eigen::MatrixXd v(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(k));
  for (std::size_t q = 0; q < k; ++q) {
    const Eigen::Index col = Eigen::Index(m - 1 - q);
    const double lambda = eig.eigenvalues()[col];
    p.variances[q] = lambda / double(m - 1);
    v.col(Eigen::Index(q)) = eig.eigenvectors().col(col) / std::sqrt(lambda);
  }
  return v;
}

// Pass 2: the components of cells [first, first + count) (k x count), from the block holding them, read once.
class ComponentBlocks {
 public:
  ComponentBlocks(const Training& t, const BrdfPrior& p, Eigen::MatrixXd v) : t_(t), p_(p), v_(std::move(v)) {}
  void operator()(std::size_t first, std::size_t count, std::span<float> out) {
    const std::size_t d = valid_cells().size(), k = std::size_t(v_.cols()), i0 = first / t_.block * t_.block;
    if (i0 != block_) {
      check_interrupt();
      std::vector<std::size_t> holes(t_.grids.size(), 0);
      read_block(t_, i0, std::min(t_.block, d - i0), x_, holes);
      map_block(x_, i0, p_.reference, p_.mean, p_.epsilon);
      block_ = i0;
    }
    if (out.size() != k * count || first + count > std::min(d, i0 + t_.block))
      throw UsageError("prior: component blocks out of range");
    parallel_for((count + kBlock - 1) / kBlock, [&](std::size_t blk) {
      const Eigen::Index a = Eigen::Index(blk * kBlock), rows = Eigen::Index(std::min(count, (blk + 1) * kBlock)) - a;
      const Eigen::MatrixXd cb = x_.middleRows(Eigen::Index(first - i0) + a, rows).cast<double>() * v_;  // rows x k
      for (std::size_t q = 0; q < k; ++q)
        for (Eigen::Index i = 0; i < rows; ++i) out[q * count + std::size_t(a + i)] = float(cb(i, Eigen::Index(q)));
    });
  }

 private:
  const Training& t_;
  const BrdfPrior& p_;
  Eigen::MatrixXd v_;
  std::size_t block_ = std::size_t(-1);
  Eigen::MatrixXf x_;
};

}  // namespace

TrainingGrid store_training_grid(const store::Store& s, const std::string& name, const std::string& label) {
  const store::GridInfo info = s.grid_info(name);
  return {.name = label,
          .wavelengths = info.wavelengths,
          .scale = info.scale,
          .read_rows = [s, name](std::size_t h0, std::size_t rows, std::span<float> out) {
            store::read_grid_rows(s, name, h0, rows, out);
          }};
}

TrainingGrid memory_training_grid(std::shared_ptr<const store::Grid> grid, const std::string& name) {
  if (grid->brdf.size() != grid->bands() * brdf::kMerlCells)
    throw UsageError("prior: grid '" + name + "' has the wrong size");
  const WavelengthGrid w = grid->wavelengths;
  const double scale = grid->scale;
  return {.name = name,
          .wavelengths = w,
          .scale = scale,
          .read_rows = [grid = std::move(grid)](std::size_t h0, std::size_t rows, std::span<float> out) {
            const std::size_t b = grid->bands();
            if (h0 + rows > std::size_t(brdf::kMerlThetaH) || out.size() != b * rows * kRow)
              throw UsageError("prior: rows out of range");
            for (std::size_t k = 0; k < b; ++k)
              std::copy_n(grid->brdf.begin() + std::ptrdiff_t(k * brdf::kMerlCells + h0 * kRow), rows * kRow,
                          out.begin() + std::ptrdiff_t(k * rows * kRow));
          }};
}

BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& o,
                      const std::function<void(const BrdfPrior&, ComponentSource)>& sink) {
  BrdfPrior p;
  const Training t = check_training(grids, o, p);
  const Eigen::MatrixXd gram = first_pass(t, p);
  ComponentBlocks blocks(t, p, solve_components(gram, o.components, p));
  sink(p, [&](std::size_t first, std::size_t count, std::span<float> out) { blocks(first, count, out); });
  return p;
}

BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& o) {
  BrdfPrior whole;
  build_prior(grids, o, [&](const BrdfPrior& p, const ComponentSource& blocks) {
    whole = p;
    const std::size_t d = p.cells(), k = p.k();
    whole.components.assign(k * d, 0.0f);
    std::vector<float> block;
    for (std::size_t first = 0; first < d; first += store::kPriorBlockCells) {
      const std::size_t count = std::min(store::kPriorBlockCells, d - first);
      block.resize(k * count);
      blocks(first, count, block);
      for (std::size_t q = 0; q < k; ++q)
        std::copy_n(block.begin() + std::ptrdiff_t(q * count), count,
                    whole.components.begin() + std::ptrdiff_t(q * d + first));
    }
  });
  return whole;
}

BrdfPrior build_prior(std::size_t count, const std::function<store::Grid(std::size_t)>& load,
                      std::span<const std::string> names, const PriorOptions& o) {
  if (names.size() != count) throw UsageError("prior: give at least 2 training grids, each named");
  std::vector<TrainingGrid> grids;
  for (std::size_t i = 0; i < count; ++i)
    grids.push_back(memory_training_grid(std::make_shared<const store::Grid>(load(i)), names[i]));
  return build_prior(grids, o);
}

}  // namespace specula::acquire
