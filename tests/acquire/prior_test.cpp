// The learned BRDF prior (acquire/prior.h, acquire/prior_resample.h) on analytic materials: a training grid is
// reproduced from all its cells, a held-out material of the family is recovered from 1 % of its cells, the
// prior round-trips through the store, and confidence is 0 where no sample falls.
#include "specula/acquire/prior.h"
#include "specula/acquire/retro_rise.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <random>

#include "specula/acquire/prior_resample.h"
#include "specula/acquire/retro_trend.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "test_support.h"
#include "ward_family.h"

using namespace specula;

namespace {

const WavelengthGrid& kBands = test::kWardBands;
using test::ward;

store::Grid grid_of(const brdf::SpectralModel& m) {
  store::Grid g;
  g.wavelengths = kBands;
  g.brdf.resize(kBands.size() * brdf::kMerlCells);
  brdf::evaluate_grid(m, g.brdf);
  return g;
}

struct Family {
  std::vector<store::Grid> grids;
  std::vector<std::string> names;
  acquire::BrdfPrior prior;
};

// Seven training materials; built once for the whole file.
const Family& family() {
  static const Family f = [] {
    Family out;
    const double params[][4] = {{0.6, 0.1, 0.05, 0.05}, {0.2, 0.5, 0.1, 0.1},   {0.4, 0.4, 0.02, 0.2},
                                {0.1, 0.1, 0.2, 0.07},  {0.7, 0.3, 0.08, 0.15}, {0.3, 0.6, 0.0, 0.1},
                                {0.5, 0.2, 0.15, 0.3}};
    for (std::size_t i = 0; i < std::size(params); ++i) {
      out.grids.push_back(grid_of(ward(params[i][0], params[i][1], params[i][2], params[i][3])));
      out.names.push_back("m" + std::to_string(i));
    }
    out.prior = acquire::build_prior(out.grids.size(), [&](std::size_t i) { return out.grids[i]; }, out.names,
                                     {.channels = 3, .components = 0, .epsilon = 1e-3});
    return out;
  }();
  return f;
}

// Observations of grid g at the given valid-cell positions, weight 1.
acquire::PriorObservations observe(const store::Grid& g, const std::vector<std::size_t>& at) {
  acquire::PriorObservations obs;
  const auto& cells = acquire::valid_cells();
  for (const std::size_t i : at) {
    obs.cell.push_back(std::uint32_t(i));
    for (std::size_t k = 0; k < g.bands(); ++k) obs.values.push_back(g.brdf[k * brdf::kMerlCells + cells[i]]);
    obs.weight.push_back(1);
  }
  return obs;
}

// Cos-weighted relative RMS of a against truth b over the valid cells and bands.
double cos_weighted_rel_rms(std::span<const float> a, std::span<const float> b, std::size_t bands) {
  const auto& cells = acquire::valid_cells();
  const auto& cosines = acquire::valid_cell_cosines();
  double num = 0, den = 0;
  for (std::size_t k = 0; k < bands; ++k)
    for (std::size_t i = 0; i < cells.size(); ++i) {
      const double w = cosines[i], x = a[k * brdf::kMerlCells + cells[i]], y = b[k * brdf::kMerlCells + cells[i]];
      num += w * w * (x - y) * (x - y);
      den += w * w * y * y;
    }
  return std::sqrt(num / den);
}

}  // namespace

TEST(Prior, ReproducesATrainingGridFromAllItsCells) {
  const Family& f = family();
  EXPECT_LE(f.prior.k(), 7u * 3u - 1u);  // null directions (channels that move together) are dropped
  EXPECT_GE(f.prior.k(), 7u);
  EXPECT_EQ(f.prior.channels(), 3u);
  const store::Grid& g = f.grids[4];
  std::vector<std::size_t> all(acquire::valid_cells().size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  std::vector<float> out(g.brdf.size(), -1.0f);
  acquire::fit_prior(f.prior, observe(g, all), {.lambda = 1e-9}, out);
  // Exactly what the prior represents: the spectra's projection on its hat functions.
  const Eigen::MatrixXd hats = acquire::hat_basis(kBands, f.prior.knots);
  const Eigen::MatrixXd proj = (hats.transpose() * hats).ldlt().solve(hats.transpose());
  std::vector<float> expect(g.brdf.size(), -1.0f);
  for (const std::uint32_t cell : acquire::valid_cells()) {
    Eigen::VectorXd s(5);
    for (int k = 0; k < 5; ++k) s[k] = g.brdf[std::size_t(k) * brdf::kMerlCells + cell];
    const Eigen::VectorXd e = hats * (proj * s).cwiseMax(0.0);
    for (int k = 0; k < 5; ++k) expect[std::size_t(k) * brdf::kMerlCells + cell] = float(e[k]);
  }
  EXPECT_LT(cos_weighted_rel_rms(out, expect, 5), 1e-4);
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c)
    if (!brdf::merl_cell_valid(brdf::merl_cell(c))) {
      ASSERT_EQ(out[c], -1.0f) << "cells below the horizon untouched";
    }
}

TEST(Prior, RecoversAHeldOutMaterialOfTheFamilyFromOnePercentOfItsCells) {
  const Family& f = family();
  const store::Grid truth = grid_of(ward(0.45, 0.25, 0.07, 0.12));  // not a training material
  std::mt19937 rng(11);
  std::vector<std::size_t> at;
  const std::size_t d = acquire::valid_cells().size();
  std::uniform_int_distribution<std::size_t> pick(0, d - 1);
  for (std::size_t n = 0; n < d / 100; ++n) at.push_back(pick(rng));
  std::vector<float> out(truth.brdf.size(), -1.0f);
  acquire::fit_prior(f.prior, observe(truth, at), {.lambda = 1e-3}, out);
  const double err = cos_weighted_rel_rms(out, truth.brdf, 5);
  // The nearest training material, for scale: the fit must do much better than picking it.
  double nearest = 1e9;
  for (const auto& g : f.grids) nearest = std::min(nearest, cos_weighted_rel_rms(g.brdf, truth.brdf, 5));
  EXPECT_LT(err, 0.1) << "nearest training material: " << nearest;
  EXPECT_LT(err, 0.5 * nearest);
}

TEST(Prior, RoundTripsThroughTheStore) {
  test::ScratchDir dir;
  const Family& f = family();
  {
    store::StoreWriter w(dir / "db.h5", {});
    acquire::write_prior(w, "p", f.prior);
    w.commit();
  }
  const store::Store s = store::Store::open(dir / "db.h5");
  EXPECT_EQ(acquire::prior_names(s), std::vector<std::string>{"p"});
  const acquire::BrdfPrior p = acquire::read_prior(s, "p");
  EXPECT_EQ(p.training, f.names);
  EXPECT_EQ(p.components, f.prior.components);
  EXPECT_EQ(p.mean, f.prior.mean);
  EXPECT_EQ(p.reference, f.prior.reference);
  EXPECT_EQ(p.ceiling, f.prior.ceiling);
  EXPECT_EQ(p.ceiling.size(), p.cells());
  EXPECT_EQ(p.variances, f.prior.variances);
  EXPECT_EQ(p.knots, f.prior.knots);
  const std::string m = test::error_of([&] { acquire::read_prior(s, "q"); });
  EXPECT_NE(m.find("db.h5: no prior 'q' (priors: p"), std::string::npos) << m;
}

// The grids `prior build` is given: a whole store is all its grids named STORE.h5:GRID (as is an open store), a
// store's grid streams from it, a grid made is kept, any other spec goes to the caller's loader, and --exclude takes
// a grid's name or its whole spec; too few grids is refused before any is opened.
TEST(Prior, TrainingGridsAreNamedAndLeftOutAsPriorBuildTakesThem) {
  Family f;
  for (int i = 0; i < 5; ++i) {
    f.grids.push_back(grid_of(ward(0.1 * i, 0.2, 0.05, 0.1)));
    f.names.push_back("m" + std::to_string(i));
  }
  test::ScratchDir dir;
  const std::string db = (dir / "db.h5").string();
  {
    store::StoreWriter w(db, {});
    for (std::size_t g = 0; g < 3; ++g) w.add_grid(f.names[g], f.grids[g]);
    w.commit();
  }
  const auto memory = acquire::memory_training_grid(std::make_shared<const store::Grid>(f.grids[3]), f.names[3]);
  std::vector<std::string> loaded;
  const auto load = [&](const std::string& spec) {
    loaded.push_back(spec);
    return acquire::reloaded_training_grid(spec, [&] { return f.grids[4]; });
  };
  const std::vector<acquire::TrainingSource> sources{db, memory, "x.spgrid", db + ":m0", store::Store::open(db)};
  const std::vector<std::string> exclude{"m1", db + ":m2"};
  const auto grids = acquire::training_grids(sources, exclude, load, "cmd", "--x");
  std::vector<std::string> names;
  for (const auto& g : grids) names.push_back(g.name);
  EXPECT_EQ(names, (std::vector<std::string>{db + ":m0", "m3", "x.spgrid", db + ":m0", db + ":m0"}));
  EXPECT_EQ(loaded, std::vector<std::string>{"x.spgrid"});
  const std::size_t row = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD, bands = kBands.size();
  std::vector<float> rows(bands * 2 * row), want(rows.size());
  for (const std::size_t g : {0, 2, 4}) {
    grids[g].read_rows(7, 2, rows);
    acquire::memory_training_grid(std::make_shared<const store::Grid>(f.grids[g == 2 ? 4 : 0]), "")
        .read_rows(7, 2, want);
    EXPECT_EQ(rows, want) << g;
  }
  const std::vector<std::string> most{"m0", "m1", "m2", "m3"};
  std::string m = test::error_of<UsageError>([&] { acquire::training_grids(sources, most, load, "cmd", "--x"); });
  EXPECT_EQ(m, "cmd: give at least 2 training grids (after --x)");
  EXPECT_EQ(loaded.size(), 1u);
  const std::vector<acquire::TrainingSource> absent{db + ":m0", "nothing.h5:a"};
  const std::vector<std::string> a{"a"};
  m = test::error_of<UsageError>([&] { acquire::training_grids(absent, a, load, "cmd", "--x"); });
  EXPECT_EQ(m, "cmd: give at least 2 training grids (after --x)");
  const std::vector<acquire::TrainingSource> missing{db + ":m0", db + ":nope"};
  m = test::error_of([&] { acquire::training_grids(missing, {}, load, "cmd", "--x"); });
  EXPECT_NE(m.find("db.h5: no grid 'nope'"), std::string::npos) << m;
}

// Grids whose every valid cell is a positive spectrum times exp(-0.01 theta_h + s(phi_d) theta_d^1.6) (theta_d the
// row's centre, degrees): each channel's ln value is a line in theta_d^1.6 in every column, so the prior learns 1.6
// for every band width of two rows or more (one row gives a flat line, a tie: 2), and the store keeps the table.
TEST(Prior, LearnsTheRetroBandsExponentFromItsTrainingGridsAndKeepsIt) {
  const WavelengthGrid bands({450, 550, 650});
  std::vector<store::Grid> grids(3);
  for (std::size_t g = 0; g < grids.size(); ++g) {
    grids[g].wavelengths = bands;
    grids[g].brdf.assign(3 * brdf::kMerlCells, -1.0f);
    for (const std::uint32_t cell : acquire::valid_cells()) {
      const brdf::MerlCell m = brdf::merl_cell(cell);
      const double f = std::exp(-0.01 * m.theta_h + (0.001 + 0.0002 * (m.phi_d % 5)) * std::pow(m.theta_d + 0.5, 1.6));
      for (std::size_t k = 0; k < 3; ++k)
        grids[g].brdf[k * brdf::kMerlCells + cell] = float((0.1 + 0.2 * double(g) + 0.05 * double(k)) * f);
    }
  }
  const std::vector<std::string> names = {"a", "b", "c"};
  const acquire::BrdfPrior prior = acquire::build_prior(grids.size(), [&](std::size_t i) { return grids[i]; }, names,
                                                        {.channels = 2, .components = 0, .epsilon = 1e-3});
  std::vector<double> want(acquire::kRetroLearnedRows, 1.6);
  want[0] = 2.0;
  EXPECT_EQ(prior.retro_exponents, want);
  test::ScratchDir dir;
  {
    store::StoreWriter w(dir / "db.h5", {});
    acquire::write_prior(w, "p", prior);
    w.commit();
  }
  EXPECT_EQ(acquire::read_prior_tables(store::Store::open(dir / "db.h5"), "p").retro_exponents, want);
}

TEST(Prior, ConfidenceIsZeroWhereNoSampleFallsAndEveryValidCellGetsData) {
  const Family& f = family();
  const brdf::Ward m = ward(0.45, 0.25, 0.07, 0.12);
  // Samples only with both directions within 40 degrees of the normal.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> angles;
  for (int n = 0; n < 200000; ++n) {
    const double ti = std::acos(1 - u(rng) * (1 - std::cos(0.7))), to = std::acos(1 - u(rng) * (1 - std::cos(0.7)));
    angles.insert(angles.end(), {ti, 0.0, to, (2 * u(rng) - 1) * std::numbers::pi});
  }
  std::vector<float> values(angles.size() / 4 * 5);
  brdf::evaluate_at(m, angles, values);
  const brdf::MemorySamples src(angles, values, 5);
  std::vector<float> grid(5 * brdf::kMerlCells), conf(brdf::kMerlCells);
  const acquire::PriorResampleStats st = acquire::resample_with_prior(src, f.prior, {}, grid, conf);
  EXPECT_EQ(st.filled_cells, acquire::valid_cells().size());
  std::size_t zero_far = 0, far = 0, high_near = 0, near = 0;
  for (const std::uint32_t c : acquire::valid_cells()) {
    ASSERT_GE(grid[c], 0.0f) << "every valid cell has data";
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(c)));
    if (a.theta_i > 1.0 || a.theta_o > 1.0) {
      ++far;
      zero_far += conf[c] == 0.0f;
    } else if (a.theta_i < 0.6 && a.theta_o < 0.6 && brdf::merl_cell(c).theta_h > 40) {
      ++near;
      high_near += conf[c] > 0.0f;
    }
  }
  EXPECT_EQ(zero_far, far);
  EXPECT_GT(far, 100000u);
  EXPECT_GT(double(high_near), 0.5 * double(near)) << near;
  EXPECT_LT(cos_weighted_rel_rms(
                grid, [&] { return grid_of(m).brdf; }(), 5),
            0.15);
}

TEST(Prior, NoiseWeightsBeatCountWeightsWhenHalfTheCellsAreTenTimesNoisier) {
  const Family& f = family();
  const store::Grid& truth = f.grids[2];  // in the prior's span: what is left is the noise the fit lets through
  const auto& cells = acquire::valid_cells();
  std::mt19937 rng(3);
  std::uniform_int_distribution<std::size_t> pick(0, cells.size() - 1);
  std::normal_distribution<double> gauss;
  std::vector<double> angles, sigma_of(cells.size(), 0.0);
  std::vector<float> values;
  for (std::size_t n = 0; n < 2000; ++n) {
    const std::size_t i = pick(rng);
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cells[i])));
    const double sigma = n % 2 ? 0.3 : 0.03;     // half the cells 10x noisier
    sigma_of[i] = sigma_of[i] > 0 ? -1 : sigma;  // -1: drawn twice, both levels
    for (int s = 0; s < 6; ++s) {
      angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
      const double e = 1 + sigma * gauss(rng);
      for (std::size_t k = 0; k < 5; ++k) values.push_back(float(truth.brdf[k * brdf::kMerlCells + cells[i]] * e));
    }
  }
  const acquire::PriorObservations obs = acquire::cell_means(brdf::MemorySamples(angles, values, 5));
  ASSERT_GT(obs.cell.size(), 1900u);
  ASSERT_EQ(obs.spread.size(), obs.values.size());
  std::vector<float> by_noise(truth.brdf.size(), -1.0f), by_count(truth.brdf.size(), -1.0f);
  acquire::fit_prior(f.prior, obs, {.lambda = 1e-9, .weights = acquire::PriorWeights::noise}, by_noise);
  acquire::fit_prior(f.prior, obs, {.lambda = 1e-9, .weights = acquire::PriorWeights::count}, by_count);
  const double e_noise = cos_weighted_rel_rms(by_noise, truth.brdf, 5),
               e_count = cos_weighted_rel_rms(by_count, truth.brdf, 5);
  // Inverse-variance weights approach a fit to the quiet half alone, whose error is about 1/5 of equal weights'.
  EXPECT_LT(e_noise, 0.5 * e_count) << e_noise << " vs " << e_count;
  // Per cell: the quiet cells weigh many times the noisy ones (100x at most; shrinkage toward the median tempers it).
  const std::vector<double> w = acquire::observation_weights(f.prior, obs, {});
  std::vector<double> quiet, noisy;
  for (std::size_t s = 0; s < obs.cell.size(); ++s) {
    if (sigma_of[obs.cell[s]] == 0.03) quiet.push_back(w[s]);
    if (sigma_of[obs.cell[s]] == 0.3) noisy.push_back(w[s]);
  }
  ASSERT_GT(quiet.size(), 900u);
  ASSERT_GT(noisy.size(), 900u);
  std::ranges::sort(quiet);
  std::ranges::sort(noisy);
  const double ratio = quiet[quiet.size() / 2] / noisy[noisy.size() / 2];
  EXPECT_GT(ratio, 5);
  EXPECT_LT(ratio, 300);
  // Without scatter (one sample a cell) the weights are the counts.
  acquire::PriorObservations single = obs;
  single.spread.clear();
  EXPECT_EQ(acquire::observation_weights(f.prior, single, {}),
            std::vector<double>(obs.weight.begin(), obs.weight.end()));
}

TEST(Prior, SamplesOwnVariancesWeighCellsOfOneSampleWhereScatterCannot) {
  const Family& f = family();
  const store::Grid& truth = f.grids[2];
  const auto& cells = acquire::valid_cells();
  std::mt19937 rng(4);
  std::uniform_int_distribution<std::size_t> pick(0, cells.size() - 1);
  std::normal_distribution<double> gauss;
  std::vector<double> angles;
  std::vector<float> values, variance;
  std::vector<int> seen(cells.size(), 0);
  for (std::size_t n = 0; n < 3000; ++n) {  // one sample a cell: no scatter to tell the noisy cells
    const std::size_t i = pick(rng);
    if (seen[i]++) continue;
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cells[i])));
    const double sigma = n % 2 ? 0.3 : 0.03;
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    const double e = 1 + sigma * gauss(rng);
    for (std::size_t k = 0; k < 5; ++k) {
      const double v = truth.brdf[k * brdf::kMerlCells + cells[i]];
      values.push_back(float(v * e));
      variance.push_back(float(v * v * sigma * sigma));
    }
  }
  const acquire::PriorObservations with = acquire::cell_means(brdf::MemorySamples(angles, values, 5, variance));
  const acquire::PriorObservations without = acquire::cell_means(brdf::MemorySamples(angles, values, 5));
  ASSERT_TRUE(with.spread_is_noise);
  ASSERT_FALSE(without.spread_is_noise);
  ASSERT_EQ(with.spread, variance) << "one sample a cell: its own variance";
  // The weights: exactly the inverse of each cell's mapped variance, relative to the median cell's (no shrinkage).
  const std::vector<double> w = acquire::observation_weights(f.prior, with, {});
  const std::vector<double> counts(without.weight.begin(), without.weight.end());
  EXPECT_EQ(acquire::observation_weights(f.prior, without, {}), counts) << "scatter of one sample: the counts";
  const Eigen::MatrixXd hats = acquire::hat_basis(kBands, f.prior.knots);
  const Eigen::MatrixXd proj = (hats.transpose() * hats).ldlt().solve(hats.transpose());
  std::vector<double> mapped(w.size());
  for (std::size_t s = 0; s < w.size(); ++s) {  // the delta method written out: channel variance / (value + eps)^2
    const double cw = acquire::valid_cell_cosines()[with.cell[s]];
    double sum = 0;
    for (Eigen::Index j = 0; j < proj.rows(); ++j) {
      double value = 0, var = 0;
      for (std::size_t k = 0; k < 5; ++k) {
        value += proj(j, Eigen::Index(k)) * with.values[s * 5 + k];
        var += proj(j, Eigen::Index(k)) * proj(j, Eigen::Index(k)) * with.spread[s * 5 + k];
      }
      sum += var * cw * cw / std::pow(std::max(value, 0.0) * cw + f.prior.epsilon, 2);
    }
    mapped[s] = sum / double(proj.rows());
  }
  std::vector<double> sorted = mapped;
  std::ranges::sort(sorted);
  const double median = sorted[sorted.size() / 2];
  for (std::size_t s = 0; s < w.size(); ++s)
    ASSERT_NEAR(w[s], median / std::max(mapped[s], 0.01 * median), 1e-6 * w[s]) << s;
  std::vector<float> by_noise(truth.brdf.size(), -1.0f), by_count(truth.brdf.size(), -1.0f);
  acquire::fit_prior(f.prior, with, {.lambda = 1e-9}, by_noise);
  acquire::fit_prior(f.prior, without, {.lambda = 1e-9}, by_count);
  const double e_noise = cos_weighted_rel_rms(by_noise, truth.brdf, 5),
               e_count = cos_weighted_rel_rms(by_count, truth.brdf, 5);
  EXPECT_LT(e_noise, 0.5 * e_count) << e_noise << " vs " << e_count;
}

TEST(Prior, ResidualsModeAddsTheShepardEstimateOfTheResidualsAgainstTheFitScaledByConfidence) {
  const Family& f = family();
  const brdf::Ward m = ward(0.45, 0.25, 0.07, 0.12);  // not a training material: the fit leaves residuals
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> angles;
  for (int n = 0; n < 20000; ++n) {  // anywhere in their cells, within 40 degrees of the normal
    const double ti = std::acos(1 - u(rng) * (1 - std::cos(0.7))), to = std::acos(1 - u(rng) * (1 - std::cos(0.7)));
    angles.insert(angles.end(), {ti, 0.0, to, (2 * u(rng) - 1) * std::numbers::pi});
  }
  std::vector<float> values(angles.size() / 4 * 5);
  brdf::evaluate_at(m, angles, values);
  const brdf::MemorySamples src(angles, values, 5);
  acquire::PriorResampleOptions o;
  o.local.k = 8;
  o.residuals = true;
  o.confidence_reach = 1;  // the whole support, so that many cells take the residuals
  std::vector<float> grid(5 * brdf::kMerlCells), conf(brdf::kMerlCells);
  acquire::resample_with_prior(src, f.prior, o, grid, conf);
  // Written out from the parts: the fit to the cell means, each sample's residual against its cell's fitted value,
  // their Shepard estimate at the cell centre, scaled by 1 - (gap / max_gap)^2, added, clamped at 0.
  std::vector<float> fitted(grid.size(), -1.0f);
  acquire::fit_prior(f.prior, acquire::cell_means(src), o.fit, fitted);
  std::vector<float> residuals(values.size());
  for (std::size_t s = 0; s < angles.size() / 4; ++s) {
    const brdf::StdAngles a{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]};
    const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
    for (std::size_t k = 0; k < 5; ++k) residuals[s * 5 + k] = values[s * 5 + k] - fitted[k * brdf::kMerlCells + cell];
  }
  const brdf::Resampler shepard(angles, residuals, 5, o.local);
  brdf::Neighbours nb;
  std::vector<float> r(5);
  std::size_t corrected = 0, checked = 0;
  const auto& cells = acquire::valid_cells();
  for (std::size_t i = 0; i < cells.size(); i += 37) {
    const std::size_t cell = cells[i];
    const brdf::StdAngles at = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cell)));
    shepard.neighbours(at, nb);
    const double g = nb.gap / o.local.max_gap, c = g < 1 ? 1 - g * g : 0.0;
    ASSERT_NEAR(conf[cell], c, 1e-6) << cell;
    const bool local = c > 0 && shepard.predict(at, r);
    for (std::size_t k = 0; k < 5; ++k) {
      const std::size_t x = k * brdf::kMerlCells + cell;
      const double expect = local ? std::max(0.0, fitted[x] + c * r[k]) : fitted[x];
      ASSERT_NEAR(grid[x], expect, 1e-5 * (1 + std::abs(expect))) << cell << " band " << k;
      if (c > 0.5) corrected += std::abs(grid[x] - fitted[x]) > 1e-3 * fitted[x];
    }
    ++checked;
  }
  ASSERT_GT(checked, 20000u);
  EXPECT_GT(corrected, 1000u) << "the residuals must change the fit where samples are near";
}

TEST(Prior, StreamedThroughAStoreEqualsABruteForcePca) {
  const Family& f = family();
  test::ScratchDir dir;
  std::vector<acquire::TrainingGrid> grids;
  for (std::size_t g = 0; g < f.grids.size(); ++g)
    grids.push_back(acquire::memory_training_grid(std::make_shared<const store::Grid>(f.grids[g]), f.names[g]));
  {  // the smallest blocks: 17 of them, each written to the store as it is made
    store::StoreWriter w(dir / "db.h5", {});
    acquire::build_prior(grids, {.channels = 3, .components = 0, .epsilon = 1e-3, .block_bytes = 1}, w, "p");
    w.commit();
  }
  const acquire::BrdfPrior p = acquire::read_prior(store::Store::open(dir / "db.h5"), "p");
  // One block or seventeen: the same sums in the same order.
  EXPECT_EQ(p.components, f.prior.components);
  EXPECT_EQ(p.variances, f.prior.variances);
  EXPECT_EQ(p.mean, f.prior.mean);
  EXPECT_EQ(p.ceiling, f.prior.ceiling);
  EXPECT_EQ(p.retro_exponents, f.prior.retro_exponents);
  EXPECT_EQ(p.retro_rise, f.prior.retro_rise);
  EXPECT_EQ(p.retro_rise.size(), acquire::retro_rise_size());
  // Brute force: the mapped, centred observations in double, their SVD.
  const auto& cells = acquire::valid_cells();
  const std::size_t d = cells.size(), c = 3, m = f.grids.size() * c;
  const Eigen::MatrixXd hats = acquire::hat_basis(kBands, p.knots);
  const Eigen::MatrixXd proj = (hats.transpose() * hats).ldlt().solve(hats.transpose());
  Eigen::MatrixXd x(static_cast<Eigen::Index>(d), static_cast<Eigen::Index>(m));
  std::vector<double> row(m);
  for (std::size_t i = 0; i < d; ++i) {
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cells[i])), wi, wo);
    for (std::size_t g = 0; g < f.grids.size(); ++g) {
      Eigen::VectorXd s(5);
      for (int k = 0; k < 5; ++k) s[k] = f.grids[g].brdf[std::size_t(k) * brdf::kMerlCells + cells[i]];
      const Eigen::VectorXd ch = (proj * s).cwiseMax(0.0) * (wi.z() * wo.z());
      for (std::size_t j = 0; j < c; ++j) x(Eigen::Index(i), Eigen::Index(g * c + j)) = ch[Eigen::Index(j)];
    }
    for (std::size_t j = 0; j < m; ++j) row[j] = x(Eigen::Index(i), Eigen::Index(j));
    std::ranges::sort(row);
    const double ref = row[m / 2];
    ASSERT_NEAR(p.reference[i], ref, 1e-6 * ref + 1e-9);
    for (std::size_t j = 0; j < m; ++j)
      x(Eigen::Index(i), Eigen::Index(j)) = std::log((x(Eigen::Index(i), Eigen::Index(j)) + 1e-3) / (ref + 1e-3));
    const double mean = x.row(Eigen::Index(i)).mean();
    ASSERT_NEAR(p.mean[i], mean, 1e-5 * (1 + std::abs(mean)));
    x.row(Eigen::Index(i)).array() -= mean;
  }
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(x, Eigen::ComputeThinU);
  ASSERT_GE(p.k(), 5u);
  for (std::size_t q = 0; q < p.k(); ++q) {
    const double sv = svd.singularValues()[Eigen::Index(q)];
    EXPECT_NEAR(p.variances[q], sv * sv / double(m - 1), 1e-4 * p.variances[0]) << q;
  }
  for (std::size_t q = 0; q < 5; ++q) {  // the leading components, up to sign
    const Eigen::Map<const Eigen::VectorXf> ours(&p.components[q * d], Eigen::Index(d));
    EXPECT_NEAR(std::abs(ours.cast<double>().dot(svd.matrixU().col(Eigen::Index(q)))), 1.0, 1e-4) << q;
  }
}

// The log mix of acquire/prior_resample.h is a weighted geometric mean of kd cc + eps and fit cc + eps, less eps, over
// cc: it lies between the two estimates, equals the fit at c = 0 and the kd-tree's at c = 1, and is never below 0,
// also where both are 0 and exp(ln eps) rounds a hair under eps (the ε of a resample is a computed value, swept here).
TEST(MixEstimates, TheLogMixLiesBetweenItsEstimatesAndNeverBelowZero) {
  const double values[] = {0, 1e-12, 1e-7, 3e-5, 1e-3, 0.2, 40};
  std::size_t n = 0;
  for (int i = 1; i < 400; ++i) {
    const double eps = 1e-3 * i / 97.0;
    for (const double c : {0.0, 0.25, 0.5, 0.75, 1.0})
      for (const double cc : {0.05, 0.3, 0.9})
        for (const double kd : values)
          for (const double fit : values) {
            const double v = acquire::mix_estimates(kd, fit, c, cc, eps, true);
            ASSERT_GE(v, 0.0) << "kd " << kd << " fit " << fit << " c " << c << " cc " << cc << " eps " << eps;
            ASSERT_GE(v, std::min(kd, fit) * (1 - 1e-12) - 1e-15);
            ASSERT_LE(v, std::max(kd, fit) * (1 + 1e-12) + 1e-15);
            if (c == 0) {
              ASSERT_EQ(v, fit);
            }
            if (c == 1) {
              ASSERT_EQ(v, kd);
            }
            const double geometric = (std::pow(kd * cc + eps, c) * std::pow(fit * cc + eps, 1 - c) - eps) / cc;
            ASSERT_NEAR(v, std::max(0.0, geometric), 1e-12 * (1 + geometric));
            ++n;
          }
  }
  EXPECT_EQ(n, 399u * 5 * 3 * 7 * 7);
  EXPECT_EQ(acquire::mix_estimates(2.0, 4.0, 0.5, 1, 1e-3, false), 3.0);
}
