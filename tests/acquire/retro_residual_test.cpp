// The carry of the log residuals into the unseen retro band, rehearsed one band higher (acquire/retro_residual.h):
// a rehearsal grid at half a Lambertian material's value everywhere is put right in the held band only by the carry,
// which is chosen; one right in the band and low above it is spoilt by the carry, which is not chosen; the errors
// equal the squared log ratio written out here at the cells each version leaves at half or doubles; two passes
// choose as one; 1 and 2 threads give the same numbers; samples from carry_rehearsal_rows up change nothing, bit for
// bit, and two rows fewer do; sizes are checked. That the samples below the band's end are held out of `kept`, whatever
// their cells, is reach_holdout's (tests/acquire/prior_reach_test.cpp).
#include "specula/acquire/retro_residual.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kCells = brdf::kMerlCells;
constexpr std::size_t kBands = 2;
constexpr float kRho[kBands] = {0.2f, 0.6f};
constexpr double kEps = 1e-12;
constexpr int kBandFirst = 5, kBandEnd = 10;  // the held band: theta_d rows [5, 10)

int row_of(std::size_t cell) { return brdf::merl_cell(cell).theta_d; }

// A Lambertian material's samples, one at the centre of every valid cell at theta_d row kBandEnd or above and theta_h
// row below kThetaH, so that every box round the band's observed cells holds some.
constexpr int kThetaH = 20;
struct Kept {
  std::vector<double> angles;
  std::vector<float> values;
  int lowest = brdf::kMerlThetaD;  // the lowest theta_d row of their cells
};
Kept kept_samples() {
  Kept k;
  for (const std::uint32_t c : valid_cells()) {
    const brdf::MerlCell m = brdf::merl_cell(c);
    if (m.theta_d < kBandEnd || m.theta_h >= kThetaH) continue;
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(m));
    k.angles.insert(k.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    k.values.insert(k.values.end(), kRho, kRho + kBands);
    k.lowest = std::min(k.lowest, m.theta_d);
  }
  return k;
}

// Every 7th valid cell of the held band below theta_h row kThetaH - 2 observed at the material's value.
PriorObservations held_band() {
  PriorObservations band;
  const auto& cells = valid_cells();
  for (std::size_t v = 0; v < cells.size(); v += 7) {
    const int row = row_of(cells[v]);
    if (row < kBandFirst || row >= kBandEnd || brdf::merl_cell(cells[v]).theta_h >= kThetaH - 2) continue;
    band.cell.push_back(std::uint32_t(v));
    band.values.insert(band.values.end(), kRho, kRho + kBands);
    band.weight.push_back(1);
  }
  return band;
}

// The material's value times below(row) at theta_d rows under kBandEnd and times above elsewhere, at every valid cell.
template <class Below>
std::vector<float> rehearsal(const Below& below, float above) {
  std::vector<float> g(kBands * kCells, -1.0f);
  for (const std::uint32_t c : valid_cells()) {
    const int row = row_of(c);
    for (std::size_t k = 0; k < kBands; ++k) g[k * kCells + c] = kRho[k] * (row < kBandEnd ? below(row) : above);
  }
  return g;
}

// The share of band's cells whose theta_d row satisfies pred.
template <class Pred>
double share(const PriorObservations& band, const Pred& pred) {
  std::size_t n = 0;
  for (const std::uint32_t v : band.cell) n += pred(row_of(valid_cells()[v]));
  return double(n) / double(band.cell.size());
}

const double kLn2Sq = std::log(2.0) * std::log(2.0);

TEST(RetroResidual, TheCarryIsChosenWhereItPutsTheBandRight) {
  const Kept k = kept_samples();
  ASSERT_EQ(k.lowest, kBandEnd);
  const brdf::MemorySamples src(k.angles, k.values, kBands);
  const PriorObservations band = held_band();
  ASSERT_GT(band.cell.size(), 2000u);
  const std::vector<float> half = rehearsal([](int) { return 0.5f; }, 0.5f);
  for (const int radius : {0, 1, 2}) {
    const RetroResidualChoice c = choose_retro_residuals(src, band, half, {.radius = radius}, kEps);
    const int carried = k.lowest - radius;  // rows [0, carried) take the lowest reached row's correction
    EXPECT_EQ(c.carried_rows, carried);
    EXPECT_EQ(c.cells, band.cell.size());
    EXPECT_TRUE(c.carried);
    EXPECT_LT(c.error_carried, 1e-8) << "radius " << radius;
    // Without the carry the band's rows below `carried` stay at half; those within the boxes come right.
    EXPECT_NEAR(c.error_plain, kLn2Sq * share(band, [&](int row) { return row < carried; }), 1e-6)
        << "radius " << radius;
  }
}

TEST(RetroResidual, TheCarryIsNotChosenWhereTheBandWasRightAlready) {
  const Kept k = kept_samples();
  const brdf::MemorySamples src(k.angles, k.values, kBands);
  const PriorObservations band = held_band();
  // Right below row 10, half above it: the samples say double, which the carry takes into the band.
  const std::vector<float> g = rehearsal([](int) { return 1.0f; }, 0.5f);
  const RetroResidualChoice c = choose_retro_residuals(src, band, g, {.radius = 1}, kEps);
  EXPECT_FALSE(c.carried);
  EXPECT_NEAR(c.error_carried, kLn2Sq, 1e-6);  // every band cell doubled
  EXPECT_NEAR(c.error_plain, kLn2Sq * share(band, [](int row) { return row >= kBandEnd - 1; }), 1e-6);
  EXPECT_LT(c.error_plain, c.error_carried);
}

TEST(RetroResidual, TwoPassesChooseAsOneAndThreadsDoNotMatter) {
  const Kept k = kept_samples();
  const brdf::MemorySamples src(k.angles, k.values, kBands);
  const PriorObservations band = held_band();
  std::mt19937 rng(5);  // a rough rehearsal: each theta_d row below the band's end off by its own factor
  std::vector<float> factor(kBandEnd);
  for (float& f : factor) f = std::uniform_real_distribution<float>(0.3f, 1.5f)(rng);
  const std::vector<float> g = rehearsal([&](int row) { return factor[std::size_t(row)]; }, 0.5f);
  const RetroResidualChoice one = choose_retro_residuals(src, band, g, {.radius = 1, .passes = 1}, kEps);
  const RetroResidualChoice two = choose_retro_residuals(src, band, g, {.radius = 1, .passes = 2}, kEps);
  EXPECT_EQ(one.carried, two.carried);
  EXPECT_NEAR(one.error_plain, two.error_plain, 1e-6);  // the second pass finds nothing left to correct
  EXPECT_NEAR(one.error_carried, two.error_carried, 1e-6);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const RetroResidualChoice serial = choose_retro_residuals(src, band, g, {.radius = 1}, kEps);
  omp_set_num_threads(2);
  const RetroResidualChoice parallel = choose_retro_residuals(src, band, g, {.radius = 1}, kEps);
  omp_set_num_threads(threads);
  EXPECT_EQ(serial.error_plain, parallel.error_plain);
  EXPECT_EQ(serial.error_carried, parallel.error_carried);
}

TEST(RetroResidual, SamplesFromTheRehearsalsRowsUpChangeNothing) {
  // Samples anywhere in their cells, each off the material by its own factor, on a rehearsal off by a factor per
  // theta_d row everywhere: every row's residuals differ, and each pass reaches further through the grid's corners.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  Kept k;
  for (const std::uint32_t c : valid_cells()) {
    const brdf::MerlCell m = brdf::merl_cell(c);
    if (m.theta_d < kBandEnd || m.theta_d >= 30 || m.theta_h >= kThetaH) continue;
    const double t = (m.theta_h + u(rng)) / brdf::kMerlThetaH;  // MERL's theta_h index is 90 sqrt(theta_h / 90 deg)
    const brdf::HalfDiff h{.theta_h = t * t * std::numbers::pi / 2,
                           .phi_h = 0,
                           .theta_d = (m.theta_d + u(rng)) * std::numbers::pi / 2 / brdf::kMerlThetaD,
                           .phi_d = (m.phi_d + u(rng)) * std::numbers::pi / brdf::kMerlPhiD};
    const brdf::StdAngles a = brdf::std_angles(h);
    if (!(a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2)) continue;
    k.angles.insert(k.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    const float f = float(0.5 + u(rng));
    for (std::size_t b = 0; b < kBands; ++b) k.values.push_back(kRho[b] * f);
    k.lowest = std::min(k.lowest, brdf::merl_cell(a).theta_d);
  }
  ASSERT_EQ(k.lowest, kBandEnd);
  std::vector<float> factor(brdf::kMerlThetaD);
  for (float& f : factor) f = std::uniform_real_distribution<float>(0.3f, 1.5f)(rng);
  std::vector<float> rough(kBands * kCells, -1.0f);
  for (const std::uint32_t c : valid_cells())
    for (std::size_t b = 0; b < kBands; ++b) rough[b * kCells + c] = kRho[b] * factor[std::size_t(row_of(c))];
  const PriorObservations band = held_band();
  // The samples whose cells lie below theta_d row `end`.
  const auto below = [&](int end, std::vector<double>& angles, std::vector<float>& values) {
    angles.clear();
    values.clear();
    for (std::size_t i = 0; i < k.angles.size() / 4; ++i) {
      const brdf::StdAngles a{k.angles[4 * i], k.angles[4 * i + 1], k.angles[4 * i + 2], k.angles[4 * i + 3]};
      if (brdf::merl_cell(a).theta_d >= end) continue;
      angles.insert(angles.end(), k.angles.begin() + std::ptrdiff_t(4 * i),
                    k.angles.begin() + std::ptrdiff_t(4 * i + 4));
      values.insert(values.end(), k.values.begin() + std::ptrdiff_t(kBands * i),
                    k.values.begin() + std::ptrdiff_t(kBands * (i + 1)));
    }
  };
  const brdf::MemorySamples all(k.angles, k.values, kBands);
  std::vector<double> angles, too_few_angles;
  std::vector<float> values, too_few_values;
  for (const int radius : {0, 1, 2})
    for (const int passes : {1, 2, 3}) {
      const LogResidualOptions o{.radius = radius, .passes = passes};
      const int end = carry_rehearsal_rows(kBandEnd, k.lowest, o);
      EXPECT_EQ(end, std::max(kBandEnd - 1, kBandEnd - radius) + passes * (radius + 1) + 1);
      below(end, angles, values);
      below(end - 2, too_few_angles, too_few_values);
      ASSERT_LT(values.size(), k.values.size());
      const RetroResidualChoice want = choose_retro_residuals(all, band, rough, o, kEps);
      const RetroResidualChoice got =
          choose_retro_residuals(brdf::MemorySamples(angles, values, kBands), band, rough, o, kEps);
      const RetroResidualChoice short_of =
          choose_retro_residuals(brdf::MemorySamples(too_few_angles, too_few_values, kBands), band, rough, o, kEps);
      EXPECT_EQ(got.carried_rows, want.carried_rows);
      EXPECT_EQ(got.error_carried, want.error_carried) << "radius " << radius << ", passes " << passes;
      EXPECT_EQ(got.error_plain, want.error_plain) << "radius " << radius << ", passes " << passes;
      // Two rows fewer and the result moves: the rows read are the rows that matter.
      EXPECT_TRUE(short_of.error_carried != want.error_carried || short_of.error_plain != want.error_plain)
          << "radius " << radius << ", passes " << passes;
    }
}

TEST(RetroResidual, SizesAndSettingsAreChecked) {
  const Kept k = kept_samples();
  const brdf::MemorySamples src(k.angles, k.values, kBands);
  const PriorObservations band = held_band();
  const std::vector<float> g = rehearsal([](int) { return 1.0f; }, 1.0f);
  EXPECT_THROW(choose_retro_residuals(src, band, std::span<const float>(g).first(kCells), {}, kEps), UsageError);
  EXPECT_THROW(choose_retro_residuals(src, PriorObservations{}, g, {}, kEps), InputError);
  EXPECT_THROW(choose_retro_residuals(src, band, g, {.radius = -1}, kEps), UsageError);
  EXPECT_THROW(choose_retro_residuals(src, band, g, {}, 0.0), UsageError);
}

}  // namespace
}  // namespace specula::acquire
