// The kd-tree's weight in the unseen cap chosen by rehearsal (acquire/cap_weight.h): a prior of glossy Ward materials
// gives the cap to the kd-tree for a flat (Lambertian) material and to the prior for a sharp Ward held out of it; the
// rehearsal holds out exactly the samples of rows [C, 2C) by the test's own cell lookup; and with a weight given,
// every cap cell is w kd + (1 - w) fit, written out here from a separate kd-tree pass and fit.
#include "specula/acquire/cap_weight.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "codec/grid_fixture.h"
#include "small_scan.h"
#include "specula/acquire/peak_cap.h"
#include "specula/acquire/scan.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

using test::grid_of;

// Six glossy Ward materials (alpha 0.01 to 0.1); built once for the file.
const BrdfPrior& glossy_prior() {
  static const BrdfPrior p = [] {
    const double family[][4] = {{0.6, 0.1, 0.08, 0.01},  {0.3, 0.2, 0.05, 0.014}, {0.5, 0.3, 0.1, 0.03},
                                {0.2, 0.6, 0.04, 0.045}, {0.7, 0.1, 0.12, 0.07},  {0.4, 0.4, 0.06, 0.1}};
    std::vector<store::Grid> grids;
    std::vector<std::string> names;
    for (const auto& f : family) {
      grids.push_back(grid_of(test::ward(f[0], f[1], f[2], f[3])));
      names.push_back("w" + std::to_string(names.size()));
    }
    return build_prior(grids.size(), [&](std::size_t i) { return grids[i]; }, names, {.channels = 3});
  }();
  return p;
}

const PriorResampleOptions kOptions{.local = {.k = 8}};

TEST(CapWeight, TheKdTreeForAFlatMaterialThePriorForASharpPeak) {
  const test::SmallScan flat = test::small_rig_scan(test::ward(0.5, 0.2, 0.0, 0.05));  // Lambertian: no lobe at all
  const brdf::MemorySamples flat_src(flat.angles, flat.values, 5);
  const CapWeightChoice f =
      choose_cap_weight(flat_src, glossy_prior(), memory_components(glossy_prior()), kOptions, {});
  const test::SmallScan sharp = test::small_rig_scan(test::ward(0.45, 0.3, 0.07, 0.02));
  const brdf::MemorySamples sharp_src(sharp.angles, sharp.values, 5);
  const CapWeightChoice s =
      choose_cap_weight(sharp_src, glossy_prior(), memory_components(glossy_prior()), kOptions, {});
  ASSERT_EQ(f.rows.size(), 5u);
  ASSERT_EQ(s.rows.size(), 5u);
  EXPECT_GT(f.held_cells, 100u);
  EXPECT_GE(f.weight, 0.75) << f.rows[0].error << " " << f.rows[4].error;
  EXPECT_LE(s.weight, 0.25) << s.rows[0].error << " " << s.rows[4].error;
}

TEST(CapWeight, HoldsOutExactlyTheRowsOneCapHigher) {
  const test::SmallScan sharp = test::small_rig_scan(test::ward(0.45, 0.3, 0.07, 0.02));
  const brdf::MemorySamples src(sharp.angles, sharp.values, 5);
  const CapWeightChoice c = choose_cap_weight(src, glossy_prior(), memory_components(glossy_prior()), kOptions, {});
  const UnseenCap cap = unseen_cap(cell_means(src));
  ASSERT_EQ(c.cap_rows, std::vector<int>(cap.begin(), cap.end()));
  std::size_t held = 0;
  for (std::size_t s = 0; s < sharp.angles.size() / 4; ++s) {
    const brdf::StdAngles a{sharp.angles[4 * s], sharp.angles[4 * s + 1], sharp.angles[4 * s + 2],
                            sharp.angles[4 * s + 3]};
    if (!(a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2)) continue;
    const brdf::MerlCell m = brdf::merl_cell(a);
    const int depth = cap[std::size_t(m.theta_d)];
    held += depth > 0 && depth < brdf::kMerlThetaH && m.theta_h >= depth && m.theta_h < std::min(2 * depth, 90);
  }
  EXPECT_GT(held, 0u);
  EXPECT_EQ(c.held_samples, held);
}

// With w = 0.5 given: linearly 0.5 kd + 0.5 fit, or (log) the geometric mean sqrt((kd cc + eps)(fit cc + eps)) less
// eps, over cc (cc = cos theta_i cos theta_o at the cell centre), where the kd-tree has support.
class CapWeightGiven : public ::testing::TestWithParam<bool> {};

TEST_P(CapWeightGiven, BlendsTheKdTreeAndTheBoundedFitInTheCap) {
  const bool log = GetParam();
  const test::SmallScan flat = test::small_rig_scan(test::ward(0.5, 0.2, 0.0, 0.05));
  const brdf::MemorySamples src(flat.angles, flat.values, 5);
  const BrdfPrior& prior = glossy_prior();
  PriorResampleOptions o = kOptions;
  o.cap_weight = 0.5;
  o.log_blend = log;
  o.blend_epsilon = 0.005;
  std::vector<float> got(5 * brdf::kMerlCells), alone(got.size()), conf(brdf::kMerlCells);
  resample_with_prior(src, prior, o, got, conf);
  o.cap_weight.reset();
  std::vector<float> conf_alone(brdf::kMerlCells);
  resample_with_prior(src, prior, o, alone, conf_alone);
  // The parts written out: the fit, bounded in the cap; the kd-tree's estimate over every sample.
  const PriorObservations obs = cell_means(src);
  const UnseenCap cap = unseen_cap(obs);
  std::vector<float> fitted(got.size(), -1.0f), kd(got.size());
  fit_prior(prior, obs, o.fit, fitted);
  std::vector<std::uint8_t> unseen(brdf::kMerlCells, 0);
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) unseen[cell] = in_unseen_cap(cap, cell);
  bound_by_ceiling(prior, unseen, fitted);
  brdf::resample_grid(src, o.local, kd);
  std::size_t blended = 0;
  for (const std::uint32_t c : valid_cells()) {
    if (!in_unseen_cap(cap, c)) {
      ASSERT_EQ(conf[c], conf_alone[c]) << c;
      for (std::size_t k = 0; k < 5; ++k) ASSERT_EQ(got[k * brdf::kMerlCells + c], alone[k * brdf::kMerlCells + c]);
      continue;
    }
    const bool support = kd[c] >= 0;
    ASSERT_EQ(conf[c], support ? 0.5f : 0.0f) << c;
    ASSERT_EQ(conf_alone[c], 0.0f) << c;
    blended += support;
    const brdf::StdAngles centre = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(c)));
    const double cc = std::cos(centre.theta_i) * std::cos(centre.theta_o), eps = *o.blend_epsilon;
    for (std::size_t k = 0; k < 5; ++k) {
      const std::size_t at = k * brdf::kMerlCells + c;
      const double want = !support ? fitted[at]
                          : log    ? (std::sqrt((kd[at] * cc + eps) * (fitted[at] * cc + eps)) - eps) / cc
                                   : 0.5 * kd[at] + 0.5 * fitted[at];
      ASSERT_NEAR(got[at], want, 1e-5 * (1 + want)) << c << " band " << k;
      ASSERT_NEAR(alone[at], fitted[at], 1e-5 * (1 + fitted[at])) << c << " band " << k;
    }
  }
  EXPECT_GT(blended, 10000u);
}

INSTANTIATE_TEST_SUITE_P(LinearAndLog, CapWeightGiven, ::testing::Bool());

}  // namespace
}  // namespace specula::acquire
