// The prior's ceiling (BrdfPrior::ceiling, acquire::bound_by_ceiling): a built prior's ceiling is the largest
// cos-weighted channel value of its training grids at each cell, recomputed here from the grids; bound_by_ceiling
// scales exactly the flagged cells above it, written out here from the cell's directions; in resampling, the cells
// of the unseen cap take the bounded fit and every other cell is what it is without the bound.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <random>

#include "codec/grid_fixture.h"
#include "small_scan.h"
#include "specula/acquire/peak_cap.h"
#include "specula/acquire/prior.h"
#include "specula/acquire/prior_resample.h"
#include "specula/acquire/scan.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "ward_family.h"

namespace specula::acquire {
namespace {

using test::grid_of;
using test::kWardBands;

struct Family {
  std::vector<store::Grid> grids;
  BrdfPrior prior;
};

// Six Ward materials of moderate peaks (specular albedo up to 0.12), 3 channels; built once for the file.
const Family& family() {
  static const Family f = [] {
    const double params[][4] = {{0.6, 0.1, 0.08, 0.01},  {0.3, 0.2, 0.05, 0.014}, {0.5, 0.3, 0.1, 0.03},
                                {0.2, 0.6, 0.04, 0.045}, {0.7, 0.1, 0.12, 0.07},  {0.4, 0.4, 0.06, 0.1}};
    Family out;
    std::vector<std::string> names;
    for (const auto& p : params) {
      out.grids.push_back(grid_of(test::ward(p[0], p[1], p[2], p[3])));
      names.push_back("w" + std::to_string(names.size()));
    }
    out.prior = build_prior(out.grids.size(), [&](std::size_t i) { return out.grids[i]; }, names, {.channels = 3});
    return out;
  }();
  return f;
}

// cos(theta_i) cos(theta_o) at the centre of MERL cell `cell`, from its directions.
double cosines_of(std::size_t cell) {
  Eigen::Vector3d wi, wo;
  brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
  return wi.z() * wo.z();
}

// The ceiling of valid cell i in 1/sr: divided by its cosines floored at 1e-6, as a fit's values are mapped back.
double limit_of(const BrdfPrior& p, std::size_t i) {
  return p.ceiling[i] / std::max(cosines_of(valid_cells()[i]), 1e-6);
}

TEST(PriorCeiling, IsTheLargestCosWeightedChannelValueOfTheTrainingGrids) {
  const Family& f = family();
  const auto& cells = valid_cells();
  ASSERT_EQ(f.prior.ceiling.size(), cells.size());
  const Eigen::MatrixXd hats = hat_basis(kWardBands, f.prior.knots);
  const Eigen::MatrixXd proj = (hats.transpose() * hats).ldlt().solve(hats.transpose());
  for (std::size_t i = 0; i < cells.size(); i += 7) {
    double top = 0;
    for (const store::Grid& g : f.grids) {
      Eigen::VectorXd s(5);
      for (int k = 0; k < 5; ++k) s[k] = g.brdf[std::size_t(k) * brdf::kMerlCells + cells[i]];
      top = std::max(top, ((proj * s).cwiseMax(0.0) * cosines_of(cells[i])).maxCoeff());
    }
    ASSERT_NEAR(f.prior.ceiling[i], top, 1e-6 * top + 1e-12) << "cell " << cells[i];
  }
}

TEST(PriorCeiling, ScalesExactlyTheFlaggedCellsAboveItAndKeepsTheirColour) {
  const Family& f = family();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> value(0.0f, 3.0f);
  std::vector<float> grid(5 * brdf::kMerlCells);
  for (float& v : grid) v = value(rng);
  std::vector<std::uint8_t> flags(brdf::kMerlCells, 0);
  for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 3) flags[cell] = 1;
  std::vector<float> expect = grid;
  std::size_t above = 0, flagged_below = 0;
  const auto& cells = valid_cells();
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::size_t cell = cells[i];
    if (!flags[cell]) continue;
    float top = 0;
    for (std::size_t k = 0; k < 5; ++k) top = std::max(top, grid[k * brdf::kMerlCells + cell]);
    const double limit = limit_of(f.prior, i);
    if (top <= limit) {
      ++flagged_below;
      continue;
    }
    ++above;
    for (std::size_t k = 0; k < 5; ++k) expect[k * brdf::kMerlCells + cell] *= float(limit / top);
  }
  ASSERT_GT(above, 1000u);
  ASSERT_GT(flagged_below, 1000u);
  std::vector<float> got = grid;
  EXPECT_EQ(bound_by_ceiling(f.prior, flags, got), above);
  for (std::size_t at = 0; at < got.size(); ++at) ASSERT_NEAR(got[at], expect[at], 1e-5f * expect[at]) << at;

  BrdfPrior old = f.prior;  // a prior written before the ceiling was kept: nothing is bounded
  old.ceiling.clear();
  got = grid;
  EXPECT_EQ(bound_by_ceiling(old, flags, got), 0u);
  EXPECT_EQ(got, grid);
  EXPECT_THROW(bound_by_ceiling(f.prior, std::span(flags).first(10), got), UsageError);
}

TEST(PriorCeiling, BoundsTheUnseenCapOfAResampleAndNoOtherCell) {
  const Family& f = family();
  // Brighter than every training material (specular albedo 0.4): the fit follows its shoulder up into the cap.
  const brdf::Ward held_out = test::ward(0.45, 0.2, 0.4, 0.02);
  const test::SmallScan scan = test::small_rig_scan(held_out);
  const brdf::MemorySamples src(scan.angles, scan.values, 5);
  const PriorObservations obs = cell_means(src);
  const UnseenCap cap = unseen_cap(obs);

  const PriorResampleOptions on{.local = {.k = 8}}, off{.local = {.k = 8}, .ceiling = false};
  std::vector<float> bounded(5 * brdf::kMerlCells), unbounded(bounded.size()), conf(brdf::kMerlCells);
  const PriorResampleStats st = resample_with_prior(src, f.prior, on, bounded, conf);
  resample_with_prior(src, f.prior, off, unbounded, conf);
  std::size_t exceeded = 0;
  const auto& cells = valid_cells();
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::size_t cell = cells[i];
    if (!in_unseen_cap(cap, cell)) {
      for (std::size_t k = 0; k < 5; ++k)
        ASSERT_EQ(bounded[k * brdf::kMerlCells + cell], unbounded[k * brdf::kMerlCells + cell]) << cell;
      continue;
    }
    ASSERT_EQ(conf[cell], 0.0f);  // the cap takes the fit alone: its values are the bounded fit's
    const double limit = limit_of(f.prior, i);
    float top = 0;
    for (std::size_t k = 0; k < 5; ++k) top = std::max(top, unbounded[k * brdf::kMerlCells + cell]);
    if (top > limit) ++exceeded;
    for (std::size_t k = 0; k < 5; ++k) {
      const float want = top > limit ? float(unbounded[k * brdf::kMerlCells + cell] * (limit / top))
                                     : unbounded[k * brdf::kMerlCells + cell];
      ASSERT_NEAR(bounded[k * brdf::kMerlCells + cell], want, 1e-5 * want) << cell;
    }
  }
  EXPECT_GT(exceeded, 100u);
  EXPECT_EQ(st.bounded_cells, exceeded);
}

}  // namespace
}  // namespace specula::acquire
