// The unseen band round retro-reflection (acquire/retro_band.h) in resampling with a prior: a rig whose lights stand
// at least 10 degrees from the camera leaves theta_d below 5 degrees without samples; there the blend takes
// w kd + (1 - w) fit (linear) or the weighted geometric mean (kd cc + eps)^w (fit cc + eps)^(1 - w) less eps, over cc
// (log) where the kd-tree has support (kd: a separately built brdf::Resampler at the cell centres; fit: the prior's
// fit alone; cc = cos theta_i cos theta_o at the centre), the fit where it has none, and every cell outside the band
// is as without a band weight.
#include "specula/acquire/retro_band.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <utility>

#include "phi_d_grid.h"
#include "specula/acquire/peak_cap.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/scan.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

using test::ward;

TEST(RetroBand, TheKdTreesWeightInTheBandNoLightReaches) {
  const double family[][4] = {
      {0.6, 0.1, 0.05, 0.05}, {0.2, 0.5, 0.1, 0.1}, {0.4, 0.4, 0.02, 0.2}, {0.1, 0.1, 0.2, 0.07}};
  std::vector<std::string> names;
  for (std::size_t i = 0; i < std::size(family); ++i) names.push_back("m" + std::to_string(i));
  const BrdfPrior prior =
      build_prior(std::size(family),
                  [&](std::size_t i) {
                    store::Grid g;
                    g.wavelengths = test::kWardBands;
                    g.brdf.resize(5 * brdf::kMerlCells);
                    brdf::evaluate_grid(ward(family[i][0], family[i][1], family[i][2], family[i][3]), g.brdf);
                    return g;
                  },
                  names, {.channels = 3});
  const ScanRig rig{.sphere_px = 100, .light_step_deg = 4, .lights = 40};
  const auto pixels = scan_pixels(rig);
  std::vector<double> angles;
  for (std::size_t j = 0; j < rig.lights; ++j) scan_light(rig, pixels, j, angles);
  std::vector<float> values(angles.size() / 4 * 5);
  brdf::evaluate_at(ward(0.45, 0.25, 0.07, 0.12), angles, values);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 0.02);
  for (float& v : values) v = float(v * (1 + noise(rng)));
  const brdf::MemorySamples src(angles, values, 5);

  // The band's depth: the lowest theta_d row of any sample above the horizon, by the test's own lookup.
  int lowest = brdf::kMerlThetaD;
  for (std::size_t s = 0; s < angles.size() / 4; ++s) {
    const brdf::StdAngles a{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]};
    if (a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2)
      lowest = std::min(lowest, brdf::merl_cell(a).theta_d);
  }
  const int rows = unseen_retro_rows(cell_means(src));
  EXPECT_EQ(rows, lowest);
  EXPECT_GE(rows, 4);  // the first light 10 degrees from the camera: theta_d of at least about 5 degrees
  EXPECT_LE(rows, 6);

  const PriorResampleOptions blend{.local = {.k = 8}, .confidence_reach = 0.1, .blend_epsilon = 0.005};
  std::vector<float> without(5 * brdf::kMerlCells), conf_without(brdf::kMerlCells);
  resample_with_prior(src, prior, blend, without, conf_without);
  std::vector<float> fitted(5 * brdf::kMerlCells, -1.0f);
  fit_prior(prior, cell_means(src), blend.fit, fitted);
  const brdf::Resampler kd(angles, values, 5, blend.local);
  const UnseenCap cap = unseen_cap(cell_means(src));
  std::size_t supported = 0, unsupported = 0;
  std::vector<float> local(5);
  for (const auto& [w, log] : {std::pair{0.0, true}, {0.5, false}, {0.5, true}, {0.75, true}, {1.0, true}}) {
    PriorResampleOptions o = blend;
    o.retro_weight = w;
    o.log_blend = log;
    std::vector<float> with(5 * brdf::kMerlCells), conf(brdf::kMerlCells);
    resample_with_prior(src, prior, o, with, conf);
    supported = unsupported = 0;
    for (const std::uint32_t c : valid_cells()) {
      const brdf::MerlCell cell = brdf::merl_cell(std::size_t(c));
      if (cell.theta_d >= rows || in_unseen_cap(cap, c)) {
        ASSERT_EQ(conf[c], conf_without[c]);
        for (std::size_t k = 0; k < 5; ++k)
          ASSERT_EQ(with[k * brdf::kMerlCells + c], without[k * brdf::kMerlCells + c]);
        continue;
      }
      const brdf::StdAngles centre = brdf::std_angles(brdf::merl_cell_centre(cell));
      const bool has = kd.predict(centre, local);
      ++(has ? supported : unsupported);
      ASSERT_EQ(conf[c], has ? float(w) : 0.0f);
      const double cc = std::cos(centre.theta_i) * std::cos(centre.theta_o), eps = *blend.blend_epsilon;
      for (std::size_t k = 0; k < 5; ++k) {
        const double fit = fitted[k * brdf::kMerlCells + c];
        const double want = !has  ? fit
                            : log ? (std::pow(local[k] * cc + eps, w) * std::pow(fit * cc + eps, 1 - w) - eps) / cc
                                  : w * local[k] + (1 - w) * fit;
        ASSERT_NEAR(with[k * brdf::kMerlCells + c], want, 1e-5 * want + 1e-9) << "w " << w << " cell " << c;
      }
    }
  }
  EXPECT_GT(supported, 10000u) << unsupported << " cells of the band without support";
}

// continue_retro on a grid whose every column's ln v is exactly a line in theta_d^p (theta_d the row's centre,
// degrees) above the band, with its own intercept and slope per band, continued with that exponent p (2, the smooth
// case, and 1.3): the band's rows come back as the same function (the least-squares line of exact points is the line);
// a column with a zero among the known rows, the other rows and the cells below the horizon are left as they were.
void expect_line_continued(double p) {
  const int first = 0, count = 5;
  std::vector<float> grid(2 * brdf::kMerlCells, -1.0f);
  const auto value = [p](std::size_t k, const brdf::MerlCell& m) {
    const double x = std::pow(m.theta_d + 0.5, p);
    return std::exp(-3.0 + 0.5 * double(k) - 0.01 * m.theta_h + (0.0005 + 0.000005 * m.phi_d) * x);
  };
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell m = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(m)) continue;
    for (std::size_t k = 0; k < 2; ++k)
      grid[k * brdf::kMerlCells + cell] = float(m.theta_d < count ? 7.0 : value(k, m));
  }
  const brdf::MerlCell dark{.theta_h = 30, .theta_d = 7, .phi_d = 40};
  grid[brdf::kMerlCells + brdf::merl_index(dark)] = 0;  // band 1 of one column has no positive value
  std::vector<float> out = grid;
  continue_retro(grid, 2, first, count, p, out);
  std::size_t continued = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell m = brdf::merl_cell(cell);
    const bool dark_column = m.theta_h == dark.theta_h && m.phi_d == dark.phi_d;
    bool known = true;  // the column has data at every row it is continued from
    for (int r = count; r < 2 * count; ++r)
      known = known && brdf::merl_cell_valid({.theta_h = m.theta_h, .theta_d = r, .phi_d = m.phi_d});
    for (std::size_t k = 0; k < 2; ++k) {
      const std::size_t at = k * brdf::kMerlCells + cell;
      if (!brdf::merl_cell_valid(m) || m.theta_d >= count || dark_column || !known) {
        ASSERT_EQ(out[at], grid[at]) << "cell " << cell << " band " << k;
        continue;
      }
      ASSERT_NEAR(out[at], value(k, m), 1e-4 * value(k, m)) << "p " << p << " cell " << cell << " band " << k;
      continued += k == 0;
    }
  }
  EXPECT_GT(continued, 50000u) << "p " << p;
}

TEST(RetroBand, TheTrendContinuedIsTheColumnsLineInThetaDToItsExponentExtended) {
  for (const double p : {2.0, 1.3}) expect_line_continued(p);
  std::vector<float> grid(2 * brdf::kMerlCells, 1.0f), out = grid;
  EXPECT_THROW(continue_retro(grid, 3, 0, 5, 2.0, out), UsageError);
  EXPECT_THROW(continue_retro(grid, 2, 0, 0, 2.0, out), UsageError);
  EXPECT_THROW(continue_retro(grid, 2, 0, 5, 0.0, out), UsageError);
}

// Known rows (5 to 9) whose ln v is a line in x = theta_d^2 plus d times residuals e, e = (1, -1, 0, -1, 1) less its
// projection on x's deviations from their mean (so orthogonal to the line): the least-squares slope is s, the residual
// sum of squares d^2 |e|^2, its squared standard error d^2 |e|^2 / (3 Sxx); the band takes the slope shrunk by
// max(0, 1 - se^2 / s^2): band 0 (s = 0.003, d = 0.01) keeps 99 % of it, band 1 (s = 0.0003, d = 0.05) is flat.
TEST(RetroBand, ATrendLostInTheNoiseIsContinuedFlat) {
  const int count = 5;
  const double slope[2] = {0.003, 0.0003}, d[2] = {0.01, 0.05};
  const auto x = [](int row) { return (row + 0.5) * (row + 0.5); };
  double x_mean = 0, sxx = 0, ex = 0, e[count] = {1, -1, 0, -1, 1}, ee = 0;
  for (int r = count; r < 2 * count; ++r) x_mean += x(r) / count;
  for (int r = count; r < 2 * count; ++r) {
    sxx += (x(r) - x_mean) * (x(r) - x_mean);
    ex += e[r - count] * (x(r) - x_mean);
  }
  for (int r = count; r < 2 * count; ++r) {
    e[r - count] -= ex / sxx * (x(r) - x_mean);
    ee += e[r - count] * e[r - count];
  }
  std::vector<float> grid(2 * brdf::kMerlCells, -1.0f);
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell m = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(m) || m.theta_d >= 2 * count) continue;
    for (std::size_t k = 0; k < 2; ++k)
      grid[k * brdf::kMerlCells + cell] =
          m.theta_d < count ? 7.0f : float(std::exp(-3.0 + slope[k] * x(m.theta_d) + d[k] * e[m.theta_d - count]));
  }
  std::vector<float> out = grid;
  continue_retro(grid, 2, 0, count, 2.0, out);
  std::size_t checked = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell m = brdf::merl_cell(cell);
    bool known = brdf::merl_cell_valid(m) && m.theta_d < count;
    for (int r = count; r < 2 * count; ++r)
      known = known && brdf::merl_cell_valid({.theta_h = m.theta_h, .theta_d = r, .phi_d = m.phi_d});
    if (!known) continue;
    for (std::size_t k = 0; k < 2; ++k) {
      const double shrink = std::max(0.0, 1.0 - d[k] * d[k] * ee / (3 * sxx) / (slope[k] * slope[k]));
      const double want = std::exp(-3.0 + slope[k] * x_mean + slope[k] * shrink * (x(m.theta_d) - x_mean));
      EXPECT_TRUE(k == 0 ? shrink > 0.99 : shrink == 0.0) << "band " << k << " shrink " << shrink;
      ASSERT_NEAR(out[k * brdf::kMerlCells + cell], want, 1e-5 * want) << "cell " << cell << " band " << k;
    }
    ++checked;
  }
  EXPECT_GT(checked, 50000u);
}

// Reciprocity at the pole. Band rows 0-4 whose ln v is A + D cos 2 phi (phi the column's centre; the cosine sums to 0
// over the 180 columns, so the row's mean of ln v is A): each cell comes back as A + keep D cos 2 phi, keep =
// sin^2(theta_d) / sin^2(5.5 degrees); a cell planted at 0 stays 0 and leaves the mean A - D cos 2 phi_z / 179 of its
// row's other columns; rows from 5 up and the cells below the horizon are untouched, bit for bit.
TEST(RetroBand, ThePolesDependenceOnPhiDFadesAsSinSquaredThetaD) {
  const int rows = 5;
  const auto A = [](std::size_t k, int h, int r) { return -2.0 - 0.01 * h + 0.1 * r + 0.3 * double(k); };
  const auto D = [](std::size_t k, int h, int r) { return 0.2 + 0.002 * h + 0.05 * r - 0.1 * double(k); };
  const auto c2 = test::cos2_phi_d;
  std::vector<float> grid = test::cos2_phi_d_grid(A, D);
  const int zh = 30, zr = 2, zp = 17;  // the planted zero, in band 0 only
  grid[brdf::merl_index({.theta_h = zh, .theta_d = zr, .phi_d = zp})] = 0.0f;
  std::vector<float> out = grid;
  const std::size_t settled = settle_retro_pole(out, 2, rows);
  const auto sin2 = [](double deg) { return std::pow(std::sin(deg * std::numbers::pi / 180), 2); };
  std::size_t checked = 0, positive = 0;
  for (int h = 0; h < brdf::kMerlThetaH; ++h)
    for (int r = 0; r < brdf::kMerlThetaD; ++r) {
      bool whole = true;  // every column of the row above the horizon
      for (int p = 0; p < brdf::kMerlPhiD; ++p)
        whole = whole && brdf::merl_cell_valid({.theta_h = h, .theta_d = r, .phi_d = p});
      for (int p = 0; p < brdf::kMerlPhiD; ++p) {
        const std::size_t cell = brdf::merl_index({.theta_h = h, .theta_d = r, .phi_d = p});
        positive += r < rows && (grid[cell] > 0 || grid[brdf::kMerlCells + cell] > 0);
        for (std::size_t k = 0; k < 2; ++k) {
          const std::size_t at = k * brdf::kMerlCells + cell;
          if (r >= rows || grid[at] <= 0) {
            ASSERT_EQ(out[at], grid[at]) << "h " << h << " r " << r << " p " << p << " band " << k;
            continue;
          }
          if (!whole) continue;
          const bool zeroed = k == 0 && h == zh && r == zr;
          const double mean = A(k, h, r) - (zeroed ? D(k, h, r) * c2(zp) / 179 : 0.0);
          const double keep = sin2(r + 0.5) / sin2(rows + 0.5);
          const double want = std::exp(mean + keep * (A(k, h, r) + D(k, h, r) * c2(p) - mean));
          ASSERT_NEAR(out[at], want, 2e-5 * want) << "h " << h << " r " << r << " p " << p << " band " << k;
          checked += k == 0;
        }
      }
    }
  EXPECT_EQ(out[brdf::merl_index({.theta_h = zh, .theta_d = zr, .phi_d = zp})], 0.0f);
  EXPECT_GT(checked, 50000u);
  EXPECT_EQ(settled, positive);
  EXPECT_EQ(settle_retro_pole(out, 2, 0), 0u);  // no band: nothing to settle
  EXPECT_THROW(settle_retro_pole(out, 3, rows), UsageError);
  EXPECT_THROW(settle_retro_pole(out, 2, -1), UsageError);
  EXPECT_THROW(settle_retro_pole(out, 2, brdf::kMerlThetaD), UsageError);
}

// A Ward material, a function of the two directions that reciprocity leaves even in the difference vector, hardly
// depends on phi_d at the pole: settled, its row 0 stays within 1 % of it below theta_h row 80. Its band rows
// spoilt by noise in ln v of +-0.3 per cell come back closer to it in every row, and in row 0 to under 5 % of the
// noise's mean square. 1 and 2 threads settle alike, bit for bit.
TEST(RetroBand, SettlingThePoleKeepsAReciprocalMaterialAndTakesOutNoise) {
  const int rows = 5;
  std::vector<float> truth(5 * brdf::kMerlCells);
  brdf::evaluate_grid(ward(0.5, 0.2, 0.08, 0.1), truth);
  std::vector<float> kept = truth;
  settle_retro_pole(kept, 5, rows);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::vector<float> noisy = truth;
  for (std::size_t at = 0; at < noisy.size(); ++at)
    if (brdf::merl_cell(at % brdf::kMerlCells).theta_d < rows && noisy[at] > 0)
      noisy[at] = float(noisy[at] * std::exp(u(rng)));
  std::vector<float> settled = noisy;
  settle_retro_pole(settled, 5, rows);
  double before[rows] = {}, after[rows] = {};
  for (std::size_t at = 0; at < truth.size(); ++at) {
    const brdf::MerlCell m = brdf::merl_cell(at % brdf::kMerlCells);
    if (m.theta_d >= rows || !(truth[at] > 0)) continue;
    if (m.theta_d == 0 && m.theta_h < 80) {
      ASSERT_NEAR(kept[at], truth[at], 0.01 * truth[at]) << "cell " << at % brdf::kMerlCells;
    }
    before[m.theta_d] += std::pow(std::log(noisy[at] / truth[at]), 2);
    after[m.theta_d] += std::pow(std::log(settled[at] / truth[at]), 2);
  }
  for (int r = 0; r < rows; ++r) EXPECT_LT(after[r], before[r]) << "row " << r;
  EXPECT_LT(after[0], 0.05 * before[0]);
  const int saved = omp_get_max_threads();
  std::vector<float> one = noisy, two = noisy;
  omp_set_num_threads(1);
  settle_retro_pole(one, 5, rows);
  omp_set_num_threads(2);
  settle_retro_pole(two, 5, rows);
  omp_set_num_threads(saved);
  EXPECT_EQ(one, two);
}

}  // namespace
}  // namespace specula::acquire
