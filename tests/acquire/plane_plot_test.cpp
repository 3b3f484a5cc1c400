// The incidence-plane and target tables against hand-placed samples and closed forms (a Lambertian model, a
// resampling of a constant), and the study's render sheet against its tone curve computed here.
#include "specula/acquire/plane_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <sstream>

#include "specula/acquire/pipeline.h"
#include "specula/acquire/study.h"
#include "specula/core/error.h"

using namespace specula;
using std::numbers::pi;

namespace {
constexpr double deg = pi / 180;

std::vector<std::vector<double>> rows_of(const std::string& table) {
  std::vector<std::vector<double>> rows;
  std::istringstream in(table);
  for (std::string line; std::getline(in, line);) {
    std::istringstream l(line);
    std::vector<double> row;
    for (std::string w; l >> w;) row.push_back(w == "NaN" ? std::nan("") : std::stod(w));
    rows.push_back(row);
  }
  return rows;
}
}  // namespace

TEST(PlanePlot, SamplesInMemoryNearThePlaneAtOneBand) {
  // On the plane towards the mirror direction, on the light's side, across the plane; two bands each.
  const std::vector<double> angles = {45 * deg, 0.3,  30 * deg, 0.3 + pi, 45 * deg, -1.0,
                                      60 * deg, -1.0, 45 * deg, 0.0,      30 * deg, pi / 2};
  const std::vector<float> values = {1, 8, 2, -1, 3, 5};
  const auto points = acquire::incidence_plane_points(angles, values, 2, 45 * deg, 2 * deg, 1);
  ASSERT_EQ(points.size(), 2u);
  EXPECT_NEAR(points[0].theta_o, 30 * deg, 1e-12);
  EXPECT_EQ(points[0].value, 8.0f);
  EXPECT_NEAR(points[1].theta_o, -60 * deg, 1e-12);
  EXPECT_EQ(points[1].value, -1.0f);
  EXPECT_EQ(acquire::plane_points_table(points), "30.000 2\n-60.000 0\n");  // cube roots, negatives as 0
  EXPECT_THROW(acquire::incidence_plane_points(angles, values, 2, 45 * deg, 2 * deg, 2), UsageError);
  EXPECT_THROW(acquire::incidence_plane_points(angles, std::span(values).first(5), 2, 45 * deg, 2 * deg, 0),
               UsageError);
}

TEST(PlanePlot, ALambertianModelAndAConstantResamplingAlongThePlane) {
  const brdf::Lambertian model(WavelengthGrid({550.0}), Eigen::VectorXd::Constant(1, 0.6));
  const double f = std::cbrt(0.6 / pi);
  const auto m = rows_of(acquire::model_plane_table(model, 40 * deg, 0));
  ASSERT_EQ(m.size(), 359u);
  for (std::size_t i = 0; i < m.size(); ++i) {
    EXPECT_DOUBLE_EQ(m[i][0], -89.5 + 0.5 * double(i));
    EXPECT_NEAR(m[i][1], f, 1e-4);
  }
  EXPECT_THROW(acquire::model_plane_table(model, 40 * deg, 1), UsageError);

  // Samples of a constant everywhere: the reconstruction is the constant wherever the lookup reads.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> angles;
  for (int i = 0; i < 4000; ++i)
    for (double a : {std::acos(u(rng)), 2 * pi * u(rng), std::acos(u(rng)), 2 * pi * u(rng)}) angles.push_back(a);
  const std::vector<float> values(angles.size() / 4, 0.125f);
  const brdf::Resampler r(angles, values, 1, {.k = 4, .weights = brdf::Weights::shepard, .max_gap = pi});
  const auto g = rows_of(acquire::grid_plane_table(r, model, 40 * deg));
  ASSERT_EQ(g.size(), 359u);
  for (const auto& row : g) {
    ASSERT_EQ(row.size(), 3u);
    EXPECT_NEAR(row[1], 0.5, 1e-4);
    EXPECT_NEAR(row[2], f, 1e-4);
  }
}

TEST(PlanePlot, TargetTableHasOneBandALineAndNaNWithoutAFactoredRecovery) {
  acquire::TargetReport t;
  t.truth = (Eigen::VectorXd(2) << 0.5, 0.25).finished();
  t.delta = (Eigen::VectorXd(2) << 0.5, 0.125).finished();
  EXPECT_EQ(acquire::target_table(t, std::vector<double>{450, 550}), "450 0.5 0.5 NaN\n550 0.25 0.125 NaN\n");
  t.filters = (Eigen::VectorXd(2) << 1, 2).finished();
  t.factored = (Eigen::VectorXd(2) << 3, 4).finished();
  EXPECT_EQ(acquire::target_table(t, std::vector<double>{450, 550}), "450 0.5 1 3\n550 0.25 2 4\n");
}

TEST(StudySheet, PanelsInRowsToneMappedByTheTruthsBrightestPixel) {
  acquire::StudyOutput s;
  s.truth = {2, {0.0, 4.0, 1.0, 9.0}, {1, 1, 1, 0}};  // the uncovered 9 is not the white
  s.grid_truth = {2, {2.0, 2.0, 2.0, 2.0}, {1, 1, 1, 1}};
  s.renders = {{2, {8.0, 0.0, 0.0, 0.0}, {1, 0, 0, 0}}};
  const acquire::Rgb8Sheet sheet = acquire::study_sheet(s, 2);
  ASSERT_EQ(sheet.width, 4u);
  ASSERT_EQ(sheet.height, 4u);
  auto grey = [&](std::size_t x, std::size_t y) {
    const std::size_t at = 3 * (y * sheet.width + x);
    EXPECT_EQ(sheet.rgb[at], sheet.rgb[at + 1]);
    EXPECT_EQ(sheet.rgb[at], sheet.rgb[at + 2]);
    return int(sheet.rgb[at]);
  };
  EXPECT_EQ(grey(0, 0), 0);
  EXPECT_EQ(grey(1, 0), 255);
  EXPECT_EQ(grey(0, 1), int(std::lround(255 * std::pow(0.25, 1 / 2.2))));
  EXPECT_EQ(grey(1, 1), 32);  // not covered: background
  EXPECT_EQ(grey(2, 0), int(std::lround(255 * std::pow(0.5, 1 / 2.2))));
  EXPECT_EQ(grey(0, 2), 255);  // clamped at white
  EXPECT_EQ(grey(1, 2), 32);
  EXPECT_EQ(grey(3, 3), 32);  // no fourth panel
  EXPECT_THROW(acquire::study_sheet(s, 0), UsageError);
}
