// The unseen cap round the specular peak (acquire/peak_cap.h) in resampling with a prior: a sharp Ward material held
// out of a prior of Ward materials, scanned by a small rig that leaves the lowest theta_h rows without samples; the
// prior in the cap brings the peak back close to the analytic truth, the kd-tree estimate there flattens it.
#include "specula/acquire/peak_cap.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "codec/grid_fixture.h"
#include "small_scan.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/scan.h"
#include "specula/core/brdf_models.h"

namespace specula::acquire {
namespace {

using test::grid_of;

const WavelengthGrid kBands = WavelengthGrid::range(400, 700, 75);  // 5 bands

brdf::Ward ward(double red, double rho_s, double alpha) {
  Eigen::VectorXd rd(5);
  for (int i = 0; i < 5; ++i) rd[i] = 0.1 + (red - 0.1) * i / 4.0;
  return brdf::Ward(kBands, rd, Eigen::VectorXd::Constant(5, rho_s), Eigen::VectorXd::Constant(5, alpha));
}

// Cos-weighted relative RMS against the truth over the valid cells of theta_h rows 0-13 (theta_h < 2.2 degrees).
double peak_rel_rms(std::span<const float> got, std::span<const float> truth) {
  double num = 0, den = 0;
  for (const std::uint32_t c : valid_cells()) {
    if (brdf::merl_cell(std::size_t(c)).theta_h > 13) continue;
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(std::size_t(c))));
    const double w = std::cos(a.theta_i) * std::cos(a.theta_o);
    for (std::size_t k = 0; k < 5; ++k) {
      const double x = truth[k * brdf::kMerlCells + c], y = got[k * brdf::kMerlCells + c];
      num += w * (x - y) * (x - y);
      den += w * x * x;
    }
  }
  return std::sqrt(num / den);
}

TEST(PeakCap, ThePriorInTheUnseenCapBringsASharpPeakBack) {
  const double family[][3] = {{0.6, 0.08, 0.01},  {0.3, 0.05, 0.014}, {0.5, 0.1, 0.03},
                              {0.2, 0.04, 0.045}, {0.7, 0.12, 0.07},  {0.4, 0.06, 0.1}};
  std::vector<store::Grid> grids;
  std::vector<std::string> names;
  for (const auto& p : family) {
    grids.push_back(grid_of(ward(p[0], p[1], p[2])));
    names.push_back("w" + std::to_string(names.size()));
  }
  const BrdfPrior prior = build_prior(grids.size(), [&](std::size_t i) { return grids[i]; }, names, {.channels = 3});
  const brdf::Ward held_out = ward(0.45, 0.07, 0.02);
  const store::Grid truth = grid_of(held_out);
  const test::SmallScan scan = test::small_rig_scan(held_out, 0.02, 11);
  const brdf::MemorySamples src(scan.angles, scan.values, 5);

  const UnseenCap cap = unseen_cap(cell_means(src));
  for (int j = 10; j <= 60; ++j) {  // the rig's lights are 4 degrees apart: every other theta_d row is unobserved
    EXPECT_GE(cap[std::size_t(j)], 3) << "theta_d row " << j;
    EXPECT_LE(cap[std::size_t(j)], 12) << "theta_d row " << j;
  }

  std::vector<float> with(5 * brdf::kMerlCells), without(with.size()), conf(brdf::kMerlCells),
      conf_without(brdf::kMerlCells);
  // The kd-tree's estimate reaching as far as it has support (r = 1), so that it would fill the cap without it.
  resample_with_prior(src, prior, {.local = {.k = 8}, .confidence_reach = 1}, with, conf);
  resample_with_prior(src, prior, {.local = {.k = 8}, .confidence_reach = 1, .prior_in_cap = false}, without,
                      conf_without);
  const double e_with = peak_rel_rms(with, truth.brdf), e_without = peak_rel_rms(without, truth.brdf);
  EXPECT_LT(e_with, 0.25);    // measured 0.17
  EXPECT_GT(e_without, 0.4);  // measured 0.54: the kd-tree's estimate flattens the peak
  EXPECT_LT(e_with, e_without / 2);
  std::size_t in_cap = 0;
  for (const std::uint32_t c : valid_cells()) {
    if (in_unseen_cap(cap, c)) {
      ++in_cap;
      ASSERT_EQ(conf[c], 0.0f);
    } else {
      ASSERT_EQ(conf[c], conf_without[c]);
      for (std::size_t k = 0; k < 5; ++k) ASSERT_EQ(with[k * brdf::kMerlCells + c], without[k * brdf::kMerlCells + c]);
    }
  }
  EXPECT_GT(in_cap, 10000u);
}

}  // namespace
}  // namespace specula::acquire
