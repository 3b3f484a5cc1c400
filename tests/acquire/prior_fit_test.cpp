// Fitting a learned prior (acquire/prior.h, fit_prior) block by block: on a small random prior and scattered
// observations, the reconstruction equals a brute-force least-squares solve (QR of the stacked, weighted and
// regularised system, not the normal equations) mapped back by hand, and is the same bit for bit whether the
// components come from memory or from the store, in blocks of one or all store chunks, on 1 or 2 threads. Made at
// some cells alone it equals the whole fit there, bit for bit, and reads only the blocks those cells and the
// observations lie in.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <cmath>
#include <random>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_geometry.h"
#include "specula/store/prior.h"
#include "test_support.h"

using namespace specula;

namespace {

constexpr std::size_t kBands = 5, kK = 4;

// A prior of kK random components over every valid cell, 3 channels on 5 bands: not learned, but every table a fit
// reads is there.
acquire::BrdfPrior random_prior() {
  acquire::BrdfPrior p;
  p.wavelengths = WavelengthGrid::range(400, 700, 75);
  p.knots = {400, 550, 700};
  p.epsilon = 1e-3;
  p.variances = {4, 2, 1, 0.5};
  p.training = {"a", "b"};
  const std::size_t d = acquire::valid_cells().size();
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> u(0, 1);
  std::normal_distribution<float> gauss;
  for (std::size_t i = 0; i < d; ++i) {
    p.reference.push_back(0.02f + 0.2f * u(rng));
    p.mean.push_back(u(rng) - 0.5f);
  }
  for (std::size_t q = 0; q < kK * d; ++q) p.components.push_back(gauss(rng) / std::sqrt(float(d) / 1000));
  return p;
}

// 30 000 observations at random cells in random order (some cells twice), and 12 000 more packed into the first
// 12 000 cells, so that one block of store chunks holds more than one piece of the fit's sums. Their channels are
// the prior's mean plus a known combination of its components plus noise (mapped domain), so the fit has something
// to find.
acquire::PriorObservations scattered(const acquire::BrdfPrior& p) {
  const std::size_t d = p.cells();
  const auto& cosines = acquire::valid_cell_cosines();
  const Eigen::MatrixXd hats = acquire::hat_basis(p.wavelengths, p.knots);
  acquire::PriorObservations obs;
  std::mt19937 rng(22);
  std::uniform_int_distribution<std::uint32_t> cell(0, std::uint32_t(d - 1));
  std::uniform_real_distribution<float> u(0, 1);
  std::normal_distribution<double> gauss(0, 0.05);
  for (std::size_t n = 0; n < 42000; ++n) {
    const std::uint32_t i = n < 30000 ? cell(rng) : std::uint32_t(n - 30000);
    Eigen::Vector3d ch;
    for (Eigen::Index j = 0; j < 3; ++j) {
      double y = p.mean[i] + gauss(rng);
      for (std::size_t q = 0; q < kK; ++q) y += double(q + 1) * double(j + 1) * p.components[q * d + i];
      ch[j] = std::max(0.0, ((p.reference[i] + p.epsilon) * std::exp(y) - p.epsilon) / cosines[i]);
    }
    const Eigen::VectorXd spec = hats * ch;
    obs.cell.push_back(i);
    for (std::size_t k = 0; k < kBands; ++k) obs.values.push_back(float(spec[Eigen::Index(k)]));
    obs.weight.push_back(1 + 4 * u(rng));
  }
  return obs;
}

// The fit written out: per channel, min |W^(1/2) (Q a - y)|^2 + lambda sum a_q^2 / variance_q by QR of the stacked
// system; the coefficients a (kK x 3).
Eigen::MatrixXd brute_force(const acquire::BrdfPrior& p, const acquire::PriorObservations& obs, double lambda) {
  const auto& cells = acquire::valid_cells();
  const auto& cosines = acquire::valid_cell_cosines();
  const std::size_t n = obs.cell.size(), d = cells.size();
  const Eigen::MatrixXd hats = acquire::hat_basis(p.wavelengths, p.knots);
  const Eigen::MatrixXd proj = (hats.transpose() * hats).ldlt().solve(hats.transpose());
  Eigen::MatrixXd a(static_cast<Eigen::Index>(n + kK), static_cast<Eigen::Index>(kK));
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n + kK), 3);
  a.bottomRows(kK).setZero();
  for (std::size_t s = 0; s < n; ++s) {
    const std::size_t i = obs.cell[s];
    const double sw = std::sqrt(double(obs.weight[s]));
    Eigen::VectorXd spec(kBands);
    for (std::size_t k = 0; k < kBands; ++k) spec[Eigen::Index(k)] = obs.values[s * kBands + k];
    const Eigen::VectorXd ch = (proj * spec).cwiseMax(0.0) * double(cosines[i]);
    for (std::size_t q = 0; q < kK; ++q) a(Eigen::Index(s), Eigen::Index(q)) = sw * p.components[q * d + i];
    for (Eigen::Index j = 0; j < 3; ++j)
      y(Eigen::Index(s), j) = sw * (std::log((ch[j] + p.epsilon) / (p.reference[i] + p.epsilon)) - p.mean[i]);
  }
  for (std::size_t q = 0; q < kK; ++q) a(Eigen::Index(n + q), Eigen::Index(q)) = std::sqrt(lambda / p.variances[q]);
  return a.householderQr().solve(y);  // kK x 3
}

// y = Q coef + mean mapped back at every valid cell and spread over the bands by the hat functions.
std::vector<float> mapped_back(const acquire::BrdfPrior& p, const Eigen::MatrixXd& coef) {
  const auto& cells = acquire::valid_cells();
  const auto& cosines = acquire::valid_cell_cosines();
  const std::size_t d = cells.size();
  const Eigen::MatrixXd hats = acquire::hat_basis(p.wavelengths, p.knots);
  std::vector<float> grid(kBands * brdf::kMerlCells, -1.0f);
  for (std::size_t i = 0; i < d; ++i) {
    Eigen::Vector3d ch;
    for (Eigen::Index j = 0; j < 3; ++j) {
      double v = p.mean[i];
      for (std::size_t q = 0; q < kK; ++q) v += coef(Eigen::Index(q), j) * p.components[q * d + i];
      ch[j] = std::max(0.0, ((p.reference[i] + p.epsilon) * std::exp(v) - p.epsilon) / std::max(cosines[i], 1e-6f));
    }
    const Eigen::VectorXd spec = hats * ch;
    for (std::size_t k = 0; k < kBands; ++k) grid[k * brdf::kMerlCells + cells[i]] = float(spec[Eigen::Index(k)]);
  }
  return grid;
}

// The largest |a - b| / (|b| + 0.001) over the valid cells and bands.
double worst_relative(std::span<const float> a, std::span<const float> b) {
  double worst = 0;
  for (std::size_t k = 0; k < kBands; ++k)
    for (const std::uint32_t c : acquire::valid_cells()) {
      const double x = a[k * brdf::kMerlCells + c], y = b[k * brdf::kMerlCells + c];
      worst = std::max(worst, std::abs(x - y) / (std::abs(y) + 1e-3));
    }
  return worst;
}

}  // namespace

TEST(PriorFit, StreamedFromTheStoreInAnyBlockOnAnyThreadsEqualsABruteForceSolve) {
  const acquire::BrdfPrior p = random_prior();
  const acquire::PriorObservations obs = scattered(p);
  test::ScratchDir dir;
  {
    store::StoreWriter w(dir / "db.h5", {});
    acquire::write_prior(w, "p", p);
    w.commit();
  }
  const store::Store s = store::Store::open(dir / "db.h5");
  const acquire::BrdfPrior tables = acquire::read_prior_tables(s, "p");
  EXPECT_TRUE(tables.components.empty());
  EXPECT_EQ(tables.mean, p.mean);
  const acquire::ComponentSource stored = acquire::store_components(s, "p");

  const int saved = omp_get_max_threads();
  const auto fit = [&](const acquire::BrdfPrior& prior, const acquire::ComponentSource& source, std::size_t bytes,
                       int threads) {
    omp_set_num_threads(threads);
    std::vector<float> grid(kBands * brdf::kMerlCells, -1.0f);
    acquire::fit_prior(prior, source, obs, {.lambda = 1e-3, .block_bytes = bytes}, grid);
    omp_set_num_threads(saved);
    return grid;
  };
  // One store chunk a block (17 blocks) or all of them in one; memory or store; one thread or two.
  const std::vector<float> ours = fit(p, acquire::memory_components(p), std::size_t(256) << 20, 2);
  EXPECT_EQ(fit(tables, stored, 1, 2), ours);
  EXPECT_EQ(fit(tables, stored, std::size_t(256) << 20, 1), ours);
  EXPECT_EQ(fit(p, acquire::memory_components(p), 3 * 4 * kK * store::kPriorBlockCells, 1), ours);

  EXPECT_LT(worst_relative(ours, mapped_back(p, brute_force(p, obs, 1e-3))), 1e-4);
  // The fit found the combination the observations were made of (up to their noise), far from the mean alone.
  Eigen::MatrixXd made(kK, 3);
  for (Eigen::Index q = 0; q < Eigen::Index(kK); ++q)
    for (Eigen::Index j = 0; j < 3; ++j) made(q, j) = double(q + 1) * double(j + 1);
  EXPECT_LT(worst_relative(ours, mapped_back(p, made)), 0.05);
  EXPECT_GT(worst_relative(ours, mapped_back(p, Eigen::MatrixXd::Zero(kK, 3))), 1.0);
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c)
    if (!brdf::merl_cell_valid(brdf::merl_cell(c))) {
      ASSERT_EQ(ours[c], -1.0f) << "cells below the horizon untouched";
    }
}

TEST(PriorFit, AtSomeCellsEqualsTheWholeFitThereAndReadsOnlyTheBlocksItNeeds) {
  const acquire::BrdfPrior p = random_prior();
  const std::size_t d = p.cells();
  acquire::PriorObservations obs;  // the observations of the first 100 000 cells only
  const acquire::PriorObservations all = scattered(p);
  for (std::size_t s = 0; s < all.cell.size(); ++s)
    if (all.cell[s] < 100000) {
      obs.cell.push_back(all.cell[s]);
      obs.weight.push_back(all.weight[s]);
      obs.values.insert(obs.values.end(), all.values.begin() + std::ptrdiff_t(s * kBands),
                        all.values.begin() + std::ptrdiff_t((s + 1) * kBands));
    }
  std::vector<std::uint32_t> at;  // 500 cells from 300 000 on and the last one
  for (std::uint32_t v = 300000; v < 300500; ++v) at.push_back(v);
  at.push_back(std::uint32_t(d - 1));
  std::vector<std::size_t> firsts;  // the first cell of every block read, in order
  const acquire::ComponentSource memory = acquire::memory_components(p);
  const acquire::ComponentSource counted = [&](std::size_t first, std::size_t count, std::span<float> out) {
    firsts.push_back(first);
    memory(first, count, out);
  };
  const acquire::PriorFitOptions o{.lambda = 1e-3, .block_bytes = 3 * 4 * kK * store::kPriorBlockCells};
  const std::size_t block = 3 * store::kPriorBlockCells;
  std::vector<float> whole(kBands * brdf::kMerlCells, -1.0f), part(whole);
  // Pass 1: the blocks holding an observation; pass 2, backwards: every block, or those holding a cell of `at`.
  std::vector<std::size_t> pass1;
  for (std::size_t i0 = 0; i0 < 100000; i0 += block) pass1.push_back(i0);
  std::vector<std::size_t> want = pass1;
  for (std::size_t i0 = (d - 1) / block * block;; i0 -= block) {
    want.push_back(i0);
    if (i0 == 0) break;
  }
  acquire::fit_prior(p, counted, obs, o, whole);
  EXPECT_EQ(firsts, want);
  firsts.clear();
  acquire::fit_prior(p, counted, obs, o, part, at);
  want = pass1;
  want.push_back((d - 1) / block * block);
  for (std::size_t i0 = 300499 / block * block; i0 + block > 300000; i0 -= block) want.push_back(i0);
  EXPECT_EQ(firsts, want);
  std::vector<std::uint8_t> in_at(d, 0);
  for (const std::uint32_t v : at) in_at[v] = 1;
  const auto& cells = acquire::valid_cells();
  for (std::size_t v = 0; v < d; ++v)
    for (std::size_t k = 0; k < kBands; ++k) {
      const std::size_t i = k * brdf::kMerlCells + cells[v];
      ASSERT_EQ(part[i], in_at[v] ? whole[i] : -1.0f) << "cell " << v << " band " << k;
    }
  std::vector<std::uint32_t> backwards = {5, 3};
  EXPECT_THROW(acquire::fit_prior(p, memory, obs, o, part, backwards), UsageError);
  std::vector<std::uint32_t> outside = {std::uint32_t(d)};
  EXPECT_THROW(acquire::fit_prior(p, memory, obs, o, part, outside), UsageError);
}

TEST(PriorFit, AComponentRangeOutsideThePriorIsRefused) {
  const acquire::BrdfPrior p = random_prior();
  std::vector<float> out(kK * 10);
  const acquire::ComponentSource memory = acquire::memory_components(p);
  memory(p.cells() - 10, 10, out);
  EXPECT_EQ(out[10], p.components[2 * p.cells() - 10]);
  EXPECT_THROW(memory(p.cells() - 9, 10, out), UsageError);
  acquire::BrdfPrior torn = p;
  torn.components.pop_back();
  EXPECT_THROW(acquire::memory_components(torn), UsageError);
}

TEST(PriorFit, ANegativeOrNonFiniteWeightIsRefused) {
  const acquire::BrdfPrior p = random_prior();
  acquire::PriorObservations obs = scattered(p);
  std::vector<float> grid(kBands * brdf::kMerlCells);
  const acquire::PriorFitOptions o{.weights = acquire::PriorWeights::count};
  obs.weight[7] = 0;
  EXPECT_NO_THROW(acquire::fit_prior(p, obs, o, grid)) << "a weight of 0 leaves the observation out";
  for (const float bad : {-1.0f, std::nanf(""), INFINITY}) {
    obs.weight[7] = bad;
    EXPECT_THROW(acquire::fit_prior(p, obs, o, grid), UsageError) << bad;
  }
}
