// The rows round the specular peak settled in phi_d (acquire/peak_rows.h): for rows with ln v = A + D cos 2 phi_d
// every cell between the cap and the settled rows becomes exp(A + keep D cos 2 phi_d), with each row's own keep, and
// with `--peak-rows N`'s keep = sin^2 theta_h / sin^2 theta_h(rows) at the row centres, written out here; the cap,
// rows keeping all, the rows above and cells <= 0 are left bit for bit; a reciprocal Ward material stays within 1 %
// where the cosines hardly vary with phi_d, noise in those rows shrinks, and 1 and 2 threads settle alike.
#include "specula/acquire/peak_rows.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "phi_d_grid.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// The centre of theta_h row h in radians, as MERL's grid places it: ((h + 0.5) / 90)^2 times 90 degrees.
double row_centre(int h) { return std::pow((h + 0.5) / 90.0, 2) * pi / 2; }

UnseenCap test_cap() {
  UnseenCap cap;
  cap.fill(5);
  cap[10] = 8;
  cap[20] = brdf::kMerlThetaH;  // a theta_d row no sample reaches
  return cap;
}

// Settles a two-band grid of ln v = A + D cos 2 phi_d (a zero planted in band 1) with `keep` and checks every cell
// against exp(A + want(h) D cos 2 phi_d) in the rows settled (want(h) < 1), and bit for bit elsewhere.
void check_settled(const std::vector<double>& keep, const std::function<double(int)>& want) {
  const UnseenCap cap = test_cap();
  const auto A = [](std::size_t k, int h, int d) { return 1.0 - 0.1 * h + 0.01 * d - 0.3 * double(k); };
  const auto D = [](std::size_t k, int h, int d) { return 0.3 + 0.01 * h - 0.002 * d + 0.1 * double(k); };
  const auto c2 = test::cos2_phi_d;
  std::vector<float> grid = test::cos2_phi_d_grid(A, D);
  const int zh = 12, zd = 30, zp = 40;  // a planted zero, band 1 only: its ring is not checked in closed form
  grid[brdf::kMerlCells + brdf::merl_index({.theta_h = zh, .theta_d = zd, .phi_d = zp})] = 0.0f;
  std::vector<float> out = grid;
  const std::size_t settled = settle_peak_rows(out, 2, cap, keep);
  std::size_t checked = 0, positive = 0;
  for (int h = 0; h < brdf::kMerlThetaH; ++h)
    for (int d = 0; d < brdf::kMerlThetaD; ++d) {
      bool whole = true;
      for (int p = 0; p < brdf::kMerlPhiD; ++p) whole = whole && brdf::merl_cell_valid({h, d, p});
      const bool in = h >= cap[std::size_t(d)] && h < int(keep.size()) && want(h) < 1;
      for (int p = 0; p < brdf::kMerlPhiD; ++p) {
        const std::size_t cell = brdf::merl_index({.theta_h = h, .theta_d = d, .phi_d = p});
        positive += in && (grid[cell] > 0 || grid[brdf::kMerlCells + cell] > 0);
        for (std::size_t k = 0; k < 2; ++k) {
          const std::size_t at = k * brdf::kMerlCells + cell;
          if (!in || grid[at] <= 0) {
            ASSERT_EQ(out[at], grid[at]) << "h " << h << " d " << d << " p " << p << " band " << k;
            continue;
          }
          if (!whole || (k == 1 && h == zh && d == zd)) continue;
          const double v = std::exp(A(k, h, d) + want(h) * D(k, h, d) * c2(p));
          ASSERT_NEAR(out[at], v, 2e-5 * v) << "h " << h << " d " << d << " p " << p << " band " << k;
          checked += k == 0;
        }
      }
    }
  EXPECT_EQ(out[brdf::kMerlCells + brdf::merl_index({.theta_h = zh, .theta_d = zd, .phi_d = zp})], 0.0f);
  EXPECT_GT(checked, 50000u);
  EXPECT_EQ(settled, positive);
}

TEST(PeakRows, ThePeaksDependenceOnPhiDFadesAsSinSquaredThetaH) {
  const int rows = 20;
  check_settled(sin2_keeps(rows), [&](int h) {
    return h < rows ? std::pow(std::sin(row_centre(h)) / std::sin(row_centre(rows)), 2) : 1.0;
  });
  EXPECT_TRUE(sin2_keeps(0).empty());
  EXPECT_THROW(sin2_keeps(-1), UsageError);
  EXPECT_THROW(sin2_keeps(brdf::kMerlThetaH), UsageError);
}

TEST(PeakRows, EachRowKeepsItsOwnShare) {
  std::vector<double> keep(20);
  for (std::size_t h = 0; h < keep.size(); ++h) keep[h] = h % 5 == 3 ? 1.0 : 0.05 * double(h % 7);
  check_settled(keep, [&](int h) { return keep[std::size_t(h)]; });
  std::vector<float> grid(2 * brdf::kMerlCells, 1.0f);
  const UnseenCap cap = test_cap();
  EXPECT_EQ(settle_peak_rows(grid, 2, cap, std::vector<double>{}), 0u);
  EXPECT_THROW(settle_peak_rows(grid, 3, cap, keep), UsageError);
  EXPECT_THROW(settle_peak_rows(grid, 2, cap, std::vector<double>(brdf::kMerlThetaH + 1, 0.5)), UsageError);
  EXPECT_THROW(settle_peak_rows(grid, 2, cap, std::vector<double>{0.5, 1.5}), UsageError);
  EXPECT_THROW(settle_peak_rows(grid, 2, cap, std::vector<double>{-0.1}), UsageError);
}

// A Ward material is a function of the two directions that reciprocity leaves even in phi_d at theta_h = 0; its
// lobe depends on theta_h alone and the rest on the cosines, which vary with phi_d as tan^2 theta_d tan^2 theta_h:
// settled, it stays within 1 % below theta_d = 60 degrees. Its rows spoilt by noise in ln v of +-0.3 per cell come
// back closer to it in every settled row. 1 and 2 threads settle alike, bit for bit.
TEST(PeakRows, SettlingThePeakKeepsAReciprocalMaterialAndTakesOutNoise) {
  const int rows = 20;
  const UnseenCap cap = test_cap();
  std::vector<float> truth(5 * brdf::kMerlCells);
  brdf::evaluate_grid(test::ward(0.5, 0.2, 0.08, 0.1), truth);
  std::vector<float> kept = truth;
  settle_peak_rows(kept, 5, cap, sin2_keeps(rows));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::vector<float> noisy = truth;
  for (std::size_t at = 0; at < noisy.size(); ++at)
    if (brdf::merl_cell(at % brdf::kMerlCells).theta_h < rows && noisy[at] > 0)
      noisy[at] = float(noisy[at] * std::exp(u(rng)));
  std::vector<float> settled = noisy;
  settle_peak_rows(settled, 5, cap, sin2_keeps(rows));
  double before[rows] = {}, after[rows] = {};
  std::size_t near = 0;
  for (std::size_t at = 0; at < truth.size(); ++at) {
    const brdf::MerlCell m = brdf::merl_cell(at % brdf::kMerlCells);
    if (m.theta_h >= rows || m.theta_h < cap[std::size_t(m.theta_d)] || !(truth[at] > 0)) continue;
    if (m.theta_d < 60) {
      ASSERT_NEAR(kept[at], truth[at], 0.01 * truth[at]) << "cell " << at % brdf::kMerlCells;
      ++near;
    }
    before[m.theta_h] += std::pow(std::log(noisy[at] / truth[at]), 2);
    after[m.theta_h] += std::pow(std::log(settled[at] / truth[at]), 2);
  }
  EXPECT_GT(near, 100000u);
  for (int h = 5; h < rows; ++h) EXPECT_LT(after[h], before[h]) << "row " << h;
  EXPECT_LT(after[5], 0.05 * before[5]);
  const int saved = omp_get_max_threads();
  std::vector<float> one = noisy, two = noisy;
  omp_set_num_threads(1);
  settle_peak_rows(one, 5, cap, sin2_keeps(rows));
  omp_set_num_threads(2);
  settle_peak_rows(two, 5, cap, sin2_keeps(rows));
  omp_set_num_threads(saved);
  EXPECT_EQ(one, two);
}

}  // namespace
}  // namespace specula::acquire
