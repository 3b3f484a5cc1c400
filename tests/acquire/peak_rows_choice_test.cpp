// The choice of the peak's rows from the scan (acquire/peak_rows_choice.h): with ln f = a cos 2 phi_d on every ring,
// the samples' spread is a sqrt(1.782) and the grid's b sqrt(1.827), the closed forms of the far (60-90 degrees) and
// near (0-15 degrees) pairs' mean squared differences, 1 - the mean of cos 2 delta over each range, so a group keeps
// (a / b)^2 1.782 / 1.827 of its departure; noise in the samples leaves the spread where it is; a grid spreading less
// than the samples keeps it all and ends the log residuals' ring rows; groups without samples below the first
// measured take its share and pass, above it keep all and end the rows; the choice is the same for 1 and 2 threads;
// settings are checked.
#include "specula/acquire/peak_rows_choice.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "specula/acquire/peak_rows.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// Samples on the theta_d rows 20, 30 and 40 of theta_h rows [lo, hi): per ring `per_ring` at theta_h within 2 % of
// the row's centre and theta_d at the row's centre, phi_d uniform, value exp(a cos 2 phi_d) times lognormal noise.
struct Scan {
  std::vector<double> angles;
  std::vector<float> values;
};
Scan ring_scan(int lo, int hi, double a, double noise, std::size_t per_ring, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> phi(0, 2 * pi), jitter(-0.02, 0.02);
  std::normal_distribution<double> gauss(0, 1);
  Scan s;
  for (int h = lo; h < hi; ++h)
    for (const int d : {20, 30, 40})
      for (std::size_t i = 0; i < per_ring; ++i) {
        brdf::HalfDiff x = brdf::merl_cell_centre({.theta_h = h, .theta_d = d});
        x.theta_h *= 1 + jitter(rng);
        x.phi_h = phi(rng);
        x.phi_d = phi(rng);
        const brdf::StdAngles w = brdf::std_angles(x);
        s.angles.insert(s.angles.end(), {w.theta_i, w.phi_i, w.theta_o, w.phi_o});
        s.values.push_back(float(std::exp(a * std::cos(2 * x.phi_d) + noise * gauss(rng))));
      }
  return s;
}

// A one-band grid of exp(b(theta_h row) cos 2 phi_d) at the cell centres.
std::vector<float> ring_grid(const std::function<double(int)>& b) {
  std::vector<float> g(brdf::kMerlCells);
  for (std::size_t c = 0; c < g.size(); ++c) {
    const brdf::MerlCell m = brdf::merl_cell(c);
    g[c] = float(std::exp(b(m.theta_h) * std::cos(2 * brdf::merl_cell_centre(m).phi_d)));
  }
  return g;
}

PeakRowsChoice choose(const Scan& s, const std::vector<float>& grid) {
  const brdf::MemorySamples src(s.angles, s.values, 1);
  return choose_peak_rows(src, grid, 1, {});
}

TEST(PeakRowsChoice, SpreadsAreTheClosedFormsOfACos2PhiDRing) {
  const Scan s = ring_scan(1, kPeakRows, 0.2, 0.0, 200, 1);
  const PeakRowsChoice c = choose(s, ring_grid([](int) { return 0.4; }));
  ASSERT_EQ(c.groups.size(), 4u);
  EXPECT_EQ(c.samples, s.values.size());
  for (const PeakRowsGroup& g : c.groups) {
    ASSERT_TRUE(g.measured) << g.first_row;
    EXPECT_NEAR(g.spread, 0.2 * std::sqrt(1.782), 0.03 * 0.2 * std::sqrt(1.782)) << g.first_row;
    EXPECT_NEAR(g.grid_spread, 0.4 * std::sqrt(1.827), 0.02 * 0.4 * std::sqrt(1.827)) << g.first_row;
    EXPECT_NEAR(g.near_rms, 0.2 * std::sqrt(0.0451), 0.1 * 0.2 * std::sqrt(0.0451)) << g.first_row;
  }
  EXPECT_EQ(c.rows, kPeakRows);  // the grid spreads twice as much as the samples: every group settled
  // Each group keeps (spread / grid spread)^2 of its departure: about (0.2^2 1.782) / (0.4^2 1.827) = 0.244.
  const std::vector<double> keep = row_keeps(c);
  ASSERT_EQ(keep.size(), std::size_t(kPeakRows));
  for (int r = 0; r < kPeakRows; ++r) {
    const PeakRowsGroup& g = c.groups[std::size_t(r / 5)];
    EXPECT_DOUBLE_EQ(keep[std::size_t(r)], std::pow(g.spread / g.grid_spread, 2)) << r;
    EXPECT_NEAR(keep[std::size_t(r)], 0.25 * 1.782 / 1.827, 0.05) << r;
  }
}

TEST(PeakRowsChoice, NoiseRaisesBothKindsOfPairsAndLeavesTheSpread) {
  const Scan quiet = ring_scan(5, 10, 0.2, 0.0, 300, 2), noisy = ring_scan(5, 10, 0.2, 0.05, 300, 2);
  const std::vector<float> grid = ring_grid([](int) { return 0.1; });
  const PeakRowsGroup q = choose(quiet, grid).groups[1], n = choose(noisy, grid).groups[1];
  EXPECT_GT(n.near_rms, 1.5 * q.near_rms);  // sqrt(0.042^2 + 2 x 0.05^2) = 0.082 against 0.042
  EXPECT_NEAR(n.spread, q.spread, 0.08 * q.spread);
}

TEST(PeakRowsChoice, RowsEndWhereTheGridSpreadsNoMoreThanTheSamples) {
  const Scan all = ring_scan(1, kPeakRows, 0.2, 0.02, 150, 3);
  const PeakRowsChoice flat = choose(all, ring_grid([](int) { return 0.1; }));
  EXPECT_EQ(flat.rows, 0);                                   // the first group already fails
  for (const double k : row_keeps(flat)) EXPECT_EQ(k, 1.0);  // a grid spreading less than the samples keeps it all
  // Rows below 10 spreading twice the samples' and those above half of it, then the other way round: the rows spreading
  // more are settled by their share (under 0.5), the others keep all, though in the second the rows have ended at 0.
  for (const bool low : {true, false}) {
    const PeakRowsChoice c = choose(all, ring_grid([&](int h) { return (h < 10) == low ? 0.4 : 0.1; }));
    EXPECT_EQ(c.rows, low ? 10 : 0);
    for (int r = 0; r < kPeakRows; ++r)
      if ((r < 10) == low)
        EXPECT_LT(row_keeps(c)[std::size_t(r)], 0.5) << r;
      else
        EXPECT_EQ(row_keeps(c)[std::size_t(r)], 1.0) << r;
  }
  // Groups without samples: passed below the first measured one (the unseen cap), ending the rows above it.
  const Scan middle = ring_scan(5, 15, 0.2, 0.02, 150, 4);
  const PeakRowsChoice c = choose(middle, ring_grid([](int) { return 0.4; }));
  EXPECT_FALSE(c.groups[0].measured);
  EXPECT_FALSE(c.groups[3].measured);
  EXPECT_EQ(c.rows, 15);
  // The cap below the first group measured takes its share; the unmeasured group above keeps all.
  for (int r = 0; r < 5; ++r) EXPECT_EQ(row_keeps(c)[std::size_t(r)], c.groups[1].keep) << r;
  EXPECT_LT(c.groups[1].keep, 0.5);
  for (int r = 15; r < kPeakRows; ++r) EXPECT_EQ(row_keeps(c)[std::size_t(r)], 1.0) << r;
  const PeakRowsChoice none = choose(Scan{}, ring_grid([](int) { return 0.4; }));
  EXPECT_EQ(none.rows, 0);  // no sample: nothing settled
  for (const double k : row_keeps(none)) EXPECT_EQ(k, 1.0);
}

TEST(PeakRowsChoice, SameForOneAndTwoThreads) {
  const Scan s = ring_scan(3, 18, 0.3, 0.03, 120, 5);
  const std::vector<float> grid = ring_grid([](int h) { return 0.05 * h; });
  omp_set_num_threads(1);
  const PeakRowsChoice one = choose(s, grid);
  omp_set_num_threads(2);
  const PeakRowsChoice two = choose(s, grid);
  EXPECT_EQ(one.rows, two.rows);
  for (std::size_t g = 0; g < one.groups.size(); ++g) {
    EXPECT_EQ(one.groups[g].spread, two.groups[g].spread);
    EXPECT_EQ(one.groups[g].grid_spread, two.groups[g].grid_spread);
    EXPECT_EQ(one.groups[g].keep, two.groups[g].keep);
  }
}

TEST(PeakRowsChoice, BadSettingsAndSizesAreRefused) {
  const Scan s = ring_scan(5, 6, 0.2, 0.0, 10, 6);
  const brdf::MemorySamples src(s.angles, s.values, 1);
  const std::vector<float> grid(brdf::kMerlCells, 1.0f);
  EXPECT_THROW(choose_peak_rows(src, grid, 2, {}), UsageError);
  EXPECT_THROW(choose_peak_rows(src, grid, 1, {.group = 0}), UsageError);
  EXPECT_THROW(choose_peak_rows(src, grid, 1, {.group = kPeakRows + 1}), UsageError);
  EXPECT_THROW(choose_peak_rows(src, grid, 1, {.theta_h_tolerance = 0}), UsageError);
  EXPECT_THROW(choose_peak_rows(src, grid, 1, {.near = 1.2}), UsageError);
  EXPECT_THROW(choose_peak_rows(src, grid, 1, {.ring_samples = 1}), UsageError);
}

}  // namespace
}  // namespace specula::acquire
