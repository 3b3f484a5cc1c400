// The correction by the samples' log residuals (acquire/log_residual.h): a grid at half a Lambertian material's
// value comes back to it exactly at the cells the samples reach (found here by dilating the samples' cells by hand)
// and stays elsewhere; on a random grid every cell equals the box mean of the residuals written out here, each sample
// looked up trilinearly by the test's own index arithmetic; below the samples' lowest theta_d row each column takes
// the correction of the lowest row the boxes reach; the result is the same for 1 and 2 threads; a held-out
// glossy material's prior resample comes closer to its truth where the samples are; settings are checked.
#include "specula/acquire/log_residual.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "codec/grid_fixture.h"
#include "small_scan.h"
#include "specula/acquire/prior.h"
#include "specula/acquire/prior_resample.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;
constexpr std::size_t kCells = brdf::kMerlCells;

// n samples at random directions above the horizon, seeded.
std::vector<double> random_angles(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> theta(0.02, 1.3), phi(-pi, pi);
  std::vector<double> a;
  for (std::size_t s = 0; s < n; ++s) a.insert(a.end(), {theta(rng), phi(rng), theta(rng), phi(rng)});
  return a;
}

// Whether cell c lies within r of a cell in `marked` on each index axis (phi_d wrapping), by brute force.
std::vector<std::uint8_t> dilated(const std::vector<std::uint8_t>& marked, int r) {
  std::vector<std::uint8_t> out(kCells, 0);
  for (std::size_t c = 0; c < kCells; ++c) {
    if (!marked[c]) continue;
    const brdf::MerlCell m = brdf::merl_cell(c);
    for (int dh = -r; dh <= r; ++dh)
      for (int dd = -r; dd <= r; ++dd)
        for (int dp = -r; dp <= r; ++dp) {
          const int h = m.theta_h + dh, d = m.theta_d + dd, p = ((m.phi_d + dp) % 180 + 180) % 180;
          if (h >= 0 && h < 90 && d >= 0 && d < 90) out[brdf::merl_index({h, d, p})] = 1;
        }
  }
  return out;
}

std::size_t cell_of(const double* a) {
  return brdf::merl_index(brdf::merl_cell(brdf::StdAngles{a[0], a[1], a[2], a[3]}));
}

TEST(LogResidual, HalfALambertianComesBackExactlyWhereTheSamplesReach) {
  const std::size_t bands = 2, n = 400;
  const std::vector<double> angles = random_angles(n, 3);
  const float rho[2] = {0.2f, 0.6f};
  std::vector<float> values(n * bands);
  for (std::size_t s = 0; s < n; ++s)
    for (std::size_t k = 0; k < bands; ++k) values[s * bands + k] = rho[k];
  const brdf::MemorySamples src(angles, values, bands);
  std::vector<std::uint8_t> marked(kCells, 0);
  for (std::size_t s = 0; s < n; ++s) marked[cell_of(&angles[4 * s])] = 1;
  for (const int radius : {0, 1, 2}) {
    std::vector<float> grid(bands * kCells, -1.0f);
    for (const std::uint32_t c : valid_cells())
      for (std::size_t k = 0; k < bands; ++k) grid[k * kCells + c] = 0.5f * rho[k];
    const LogResidualStats st =
        correct_by_log_residuals(src, {.radius = radius, .into_retro_band = false}, 1e-12, grid);
    const std::vector<std::uint8_t> reach = dilated(marked, radius);
    std::size_t reached = 0;
    for (const std::uint32_t c : valid_cells()) {
      reached += reach[c];
      for (std::size_t k = 0; k < bands; ++k)
        ASSERT_NEAR(grid[k * kCells + c], reach[c] ? rho[k] : 0.5 * rho[k], 1e-5 * rho[k]) << radius << " " << c;
    }
    EXPECT_EQ(st.corrected_cells, reached);
    EXPECT_EQ(st.samples, n);
    EXPECT_NEAR(st.rms_before, std::log(2.0), 1e-6);
    if (radius == 0) {  // a sample's other trilinear corners lie outside its own cell and stay at half
      EXPECT_GT(st.rms_after, 0.05);
    } else {
      EXPECT_LT(st.rms_after, 1e-5);
    }
    for (std::size_t c = 0; c < kCells; ++c)
      if (!brdf::merl_cell_valid(brdf::merl_cell(c))) {
        ASSERT_EQ(grid[c], -1.0f);
      }
    // Without the measure after the passes: the same grid, bit for bit, and no rms_after.
    std::vector<float> unmeasured(bands * kCells, -1.0f);
    for (const std::uint32_t c : valid_cells())
      for (std::size_t k = 0; k < bands; ++k) unmeasured[k * kCells + c] = 0.5f * rho[k];
    const LogResidualStats quiet = correct_by_log_residuals(
        src, {.radius = radius, .into_retro_band = false, .measure_after = false}, 1e-12, unmeasured);
    EXPECT_EQ(unmeasured, grid);
    EXPECT_EQ(quiet.rms_after, 0.0);
    EXPECT_EQ(quiet.rms_before, st.rms_before);
    EXPECT_EQ(quiet.corrected_cells, st.corrected_cells);
  }
}

// The grid looked up at a sample as the test reads the index space: coordinate x = 90 sqrt(theta_h / (pi/2)) - 1/2
// (and likewise theta_d, phi_d over 180), the centres floor(x) and floor(x) + 1 clamped (phi_d wrapped).
double lookup(const std::vector<float>& grid, std::size_t k, const brdf::HalfDiff& h) {
  const double phi = h.phi_d < 0 ? h.phi_d + pi : h.phi_d;
  const double x[3] = {90 * std::sqrt(h.theta_h / (pi / 2)) - 0.5, 90 * h.theta_d / (pi / 2) - 0.5,
                       180 * phi / pi - 0.5};
  int lo[3], hi[3];
  double t[3];
  for (int a = 0; a < 3; ++a) {
    const double v = a < 2 ? std::clamp(x[a], 0.0, 89.0) : x[a];
    lo[a] = int(std::floor(v)), t[a] = v - std::floor(v), hi[a] = lo[a] + 1;
    if (a < 2)
      hi[a] = std::min(hi[a], 89);
    else
      lo[a] = (lo[a] + 180) % 180, hi[a] = (hi[a] + 180) % 180;
  }
  double sum = 0, weight = 0;
  for (int c = 0; c < 8; ++c) {
    const double w = (c & 1 ? t[0] : 1 - t[0]) * (c & 2 ? t[1] : 1 - t[1]) * (c & 4 ? t[2] : 1 - t[2]);
    const float v =
        grid[k * kCells + brdf::merl_index({c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]})];
    if (w > 0 && v >= 0) sum += w * v, weight += w;
  }
  return sum / weight;
}

TEST(LogResidual, EachCellIsTheBoxMeanOfTheResidualsWrittenOut) {
  const std::size_t bands = 2, n = 300;
  const double eps = 0.01;
  const std::vector<double> angles = random_angles(n, 5);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.5, 2.0);
  std::vector<float> values(n * bands), grid(bands * kCells, -1.0f);
  for (float& v : values) v = float(u(rng));
  for (const std::uint32_t c : valid_cells())
    for (std::size_t k = 0; k < bands; ++k) grid[k * kCells + c] = float(u(rng));
  const std::vector<float> before = grid;
  correct_by_log_residuals(brdf::MemorySamples(angles, values, bands), {.radius = 1, .into_retro_band = false}, eps,
                           grid);
  std::vector<double> residual(n * bands);
  for (std::size_t s = 0; s < n; ++s) {
    const double* a = &angles[4 * s];
    const double cc = std::cos(a[0]) * std::cos(a[2]);
    const brdf::HalfDiff h = brdf::half_diff(brdf::StdAngles{a[0], a[1], a[2], a[3]});
    for (std::size_t k = 0; k < bands; ++k)
      residual[s * bands + k] = std::log((values[s * bands + k] * cc + eps) / (lookup(before, k, h) * cc + eps));
  }
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  std::size_t checked = 0, moved = 0;
  for (std::size_t i = 0; i < cells.size(); i += 97) {
    const brdf::MerlCell m = brdf::merl_cell(std::size_t(cells[i]));
    std::vector<double> sum(bands, 0.0);
    std::size_t count = 0;
    for (std::size_t s = 0; s < n; ++s) {
      const brdf::MerlCell c = brdf::merl_cell(cell_of(&angles[4 * s]));
      const int dp = std::abs(c.phi_d - m.phi_d);
      if (std::abs(c.theta_h - m.theta_h) > 1 || std::abs(c.theta_d - m.theta_d) > 1 || std::min(dp, 180 - dp) > 1)
        continue;
      ++count;
      for (std::size_t k = 0; k < bands; ++k) sum[k] += residual[s * bands + k];
    }
    for (std::size_t k = 0; k < bands; ++k) {
      const double v = before[k * kCells + cells[i]], cc = cosines[i];
      const double want = count ? std::max(0.0, (std::exp(sum[k] / double(count)) * (v * cc + eps) - eps) / cc) : v;
      ASSERT_NEAR(grid[k * kCells + cells[i]], want, 1e-4 * want) << i << " " << count;
    }
    ++checked, moved += count > 0;
  }
  EXPECT_GT(checked, 10000u);
  EXPECT_GT(moved, 30u);
}

// Round the peak (theta_h rows [ring_from[d], ring_rows)) a cell's box spans every phi_d: each cell there is the
// mean of the residuals of the samples within one theta_h and theta_d row of it, anywhere on the ring, written out
// here; every other cell (a theta_d row whose rings start higher, the rows above) keeps the box of one cell.
TEST(LogResidual, RoundThePeakEachCellIsTheMeanOverItsWholeRing) {
  const std::size_t bands = 1, n = 4000;
  const double eps = 0.01;
  const std::vector<double> angles = random_angles(n, 11);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0.5, 2.0);
  std::vector<float> values(n * bands), grid(bands * kCells, -1.0f);
  for (float& v : values) v = float(u(rng));
  for (const std::uint32_t c : valid_cells()) grid[c] = float(u(rng));
  const std::vector<float> before = grid;
  LogResidualOptions o{.radius = 1, .ring_rows = 30};
  o.ring_from.fill(3);
  o.ring_from[40] = 30;  // no rings in theta_d row 40
  correct_by_log_residuals(brdf::MemorySamples(angles, values, bands), o, eps, grid);
  std::vector<double> residual(n);
  std::vector<brdf::MerlCell> at(n);
  for (std::size_t s = 0; s < n; ++s) {
    const double* a = &angles[4 * s];
    const double cc = std::cos(a[0]) * std::cos(a[2]);
    const brdf::HalfDiff h = brdf::half_diff(brdf::StdAngles{a[0], a[1], a[2], a[3]});
    residual[s] = std::log((values[s] * cc + eps) / (lookup(before, 0, h) * cc + eps));
    at[s] = brdf::merl_cell(cell_of(a));
  }
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  std::size_t in_ring = 0, moved_in_ring = 0, outside = 0;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const brdf::MerlCell m = brdf::merl_cell(std::size_t(cells[i]));
    if (m.theta_h >= 32 || (m.theta_d != 40 && m.theta_d % 7 != 0)) continue;
    const bool ring = m.theta_h >= o.ring_from[std::size_t(m.theta_d)] && m.theta_h < o.ring_rows;
    double sum = 0;
    std::size_t count = 0;
    for (std::size_t s = 0; s < n; ++s) {
      const int dp = std::abs(at[s].phi_d - m.phi_d);
      if (std::abs(at[s].theta_h - m.theta_h) > 1 || std::abs(at[s].theta_d - m.theta_d) > 1 ||
          (!ring && std::min(dp, 180 - dp) > 1))
        continue;
      ++count, sum += residual[s];
    }
    const double v = before[cells[i]], cc = cosines[i];
    const double want = count ? std::max(0.0, (std::exp(sum / double(count)) * (v * cc + eps) - eps) / cc) : v;
    ASSERT_NEAR(grid[cells[i]], want, 1e-4 * want) << "h " << m.theta_h << " d " << m.theta_d << " p " << m.phi_d;
    if (ring)
      ++in_ring, moved_in_ring += count > 0;
    else
      ++outside;
  }
  EXPECT_GT(moved_in_ring, 2000u);
  EXPECT_GT(in_ring, moved_in_ring);
  EXPECT_GT(outside, 5000u);
  LogResidualOptions bad{.ring_rows = 90};
  EXPECT_THROW(correct_by_log_residuals(brdf::MemorySamples(angles, values, bands), bad, eps, grid), UsageError);
}

TEST(LogResidual, TheLowestRowsMeansAreCarriedIntoTheRetroBandBelow) {
  const std::size_t bands = 1;
  const std::vector<double> all = random_angles(3000, 9);
  std::vector<double> angles;
  int lowest = 90;
  for (std::size_t s = 0; s < all.size() / 4; ++s) {
    const int row = brdf::merl_cell(cell_of(&all[4 * s])).theta_d;
    if (row < 10) continue;  // a band of ten theta_d rows no sample reaches
    angles.insert(angles.end(), &all[4 * s], &all[4 * s] + 4);
    lowest = std::min(lowest, row);
  }
  const std::size_t n = angles.size() / 4;
  const std::vector<float> values(n, 0.4f);
  std::vector<std::uint8_t> marked(kCells, 0);
  for (std::size_t s = 0; s < n; ++s) marked[cell_of(&angles[4 * s])] = 1;
  const std::vector<std::uint8_t> reach = dilated(marked, 1);
  std::vector<float> grid(kCells, -1.0f);
  for (const std::uint32_t c : valid_cells()) grid[c] = 0.2f;
  const LogResidualStats st =
      correct_by_log_residuals(brdf::MemorySamples(angles, values, bands), {.into_retro_band = true}, 1e-12, grid);
  ASSERT_EQ(lowest, 10);
  EXPECT_EQ(st.carried_rows, 9);
  std::size_t carried = 0;
  for (const std::uint32_t c : valid_cells()) {
    brdf::MerlCell m = brdf::merl_cell(std::size_t(c));
    if (m.theta_d < 9) m.theta_d = 9, carried += reach[brdf::merl_index(m)];
    ASSERT_NEAR(grid[c], reach[brdf::merl_index(m)] ? 0.4 : 0.2, 1e-6) << c;
  }
  EXPECT_GT(carried, 1000u);
}

TEST(LogResidual, TheSameForOneAndTwoThreads) {
  const test::SmallScan scan = test::small_rig_scan(test::ward(0.5, 0.2, 0.08, 0.05), 0.02, 1);
  const brdf::MemorySamples src(scan.angles, scan.values, 5);
  const store::Grid start = test::grid_of(test::ward(0.4, 0.3, 0.05, 0.08));
  std::vector<std::vector<float>> out;
  const int saved = omp_get_max_threads();
  for (const int threads : {1, 2}) {
    omp_set_num_threads(threads);
    out.push_back(start.brdf);
    correct_by_log_residuals(src, {.radius = 1, .passes = 2}, 1e-3, out.back());
  }
  omp_set_num_threads(saved);
  EXPECT_TRUE(out[0] == out[1]);
  EXPECT_FALSE(out[0] == start.brdf);
}

// Six glossy Ward materials (alpha 0.01 to 0.1), as the cap's tests use.
BrdfPrior glossy_prior() {
  const double family[][4] = {{0.6, 0.1, 0.08, 0.01},  {0.3, 0.2, 0.05, 0.014}, {0.5, 0.3, 0.1, 0.03},
                              {0.2, 0.6, 0.04, 0.045}, {0.7, 0.1, 0.12, 0.07},  {0.4, 0.4, 0.06, 0.1}};
  std::vector<store::Grid> grids;
  std::vector<std::string> names;
  for (const auto& f : family) {
    grids.push_back(test::grid_of(test::ward(f[0], f[1], f[2], f[3])));
    names.push_back("w" + std::to_string(names.size()));
  }
  return build_prior(grids.size(), [&](std::size_t i) { return grids[i]; }, names, {.channels = 3});
}

// The mean over bands and the observed cells (a sample in them) of the squared log error against the truth.
double observed_error(const std::vector<float>& grid, const store::Grid& truth, const std::vector<std::uint8_t>& seen) {
  double sum = 0;
  std::size_t n = 0;
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  for (std::size_t i = 0; i < cells.size(); ++i) {
    if (!seen[cells[i]]) continue;
    for (std::size_t k = 0; k < 5; ++k) {
      const double a = grid[k * kCells + cells[i]] * cosines[i], b = truth.brdf[k * kCells + cells[i]] * cosines[i];
      sum += std::pow(std::log((a + 1e-3) / (b + 1e-3)), 2), ++n;
    }
  }
  return sum / double(n);
}

TEST(LogResidual, AHeldOutMaterialComesCloserToItsTruthWhereTheSamplesAre) {
  const brdf::Ward held = test::ward(0.45, 0.3, 0.07, 0.02);
  const test::SmallScan scan = test::small_rig_scan(held, 0.02, 2);
  const brdf::MemorySamples src(scan.angles, scan.values, 5);
  const BrdfPrior prior = glossy_prior();
  std::vector<float> grid(5 * kCells), confidence(kCells);
  resample_with_prior(src, prior, PriorResampleOptions{.local = {.k = 8}}, grid, confidence);
  const store::Grid truth = test::grid_of(held);
  std::vector<std::uint8_t> seen(kCells, 0);
  for (std::size_t s = 0; s < src.size(); ++s) seen[cell_of(&scan.angles[4 * s])] = 1;
  const double before = observed_error(grid, truth, seen);
  correct_by_log_residuals(src, {}, prior.epsilon, grid);
  const double after = observed_error(grid, truth, seen);
  EXPECT_LT(after, 0.5 * before) << before << " -> " << after;
}

TEST(LogResidual, SettingsAndSizesAreChecked) {
  const std::vector<double> angles = random_angles(4, 1);
  const std::vector<float> values(4, 1.0f);
  const brdf::MemorySamples src(angles, values, 1);
  std::vector<float> grid(kCells, 1.0f), short_grid(kCells - 1, 1.0f);
  EXPECT_THROW(correct_by_log_residuals(src, {}, 1e-3, short_grid), UsageError);
  EXPECT_THROW(correct_by_log_residuals(src, {.radius = -1}, 1e-3, grid), UsageError);
  EXPECT_THROW(correct_by_log_residuals(src, {.radius = 11}, 1e-3, grid), UsageError);
  EXPECT_THROW(correct_by_log_residuals(src, {.passes = 0}, 1e-3, grid), UsageError);
  EXPECT_THROW(correct_by_log_residuals(src, {}, 0.0, grid), UsageError);
  EXPECT_NO_THROW(correct_by_log_residuals(src, {}, 1e-3, grid));
}

}  // namespace
}  // namespace specula::acquire
