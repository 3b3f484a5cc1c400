#include "specula/core/wavelengths.h"

#include <gtest/gtest.h>

#include <vector>

#include "specula/core/error.h"

using specula::WavelengthGrid;

TEST(WavelengthGrid, RangeIncludesLast) {
  auto g = WavelengthGrid::range(420, 720, 10);
  ASSERT_EQ(g.size(), 31u);
  EXPECT_DOUBLE_EQ(g.front(), 420);
  EXPECT_DOUBLE_EQ(g.back(), 720);
  EXPECT_TRUE(g.uniform());
  EXPECT_DOUBLE_EQ(g.step(), 10);
  EXPECT_EQ(g.describe(), "31 bands 420-720 nm step 10");
}

TEST(WavelengthGrid, ParseRangeAndList) {
  EXPECT_TRUE(WavelengthGrid::parse("400:700:10").approx_equal(WavelengthGrid::range(400, 700, 10)));
  auto g = WavelengthGrid::parse("450, 550,650.5");
  ASSERT_EQ(g.size(), 3u);
  EXPECT_DOUBLE_EQ(g[2], 650.5);
  EXPECT_FALSE(g.uniform());
}

TEST(WavelengthGrid, RejectsBadInput) {
  EXPECT_THROW(WavelengthGrid::parse("400:700"), specula::UsageError);
  EXPECT_THROW(WavelengthGrid::parse("400:abc:10"), specula::UsageError);
  EXPECT_THROW(WavelengthGrid::parse("700:400:10"), specula::UsageError);
  EXPECT_THROW(WavelengthGrid::parse("500,450"), specula::UsageError);
  EXPECT_THROW(WavelengthGrid({400, 400}), specula::InputError);
  EXPECT_THROW(WavelengthGrid({400, std::nan("")}), specula::InputError);
  try {
    WavelengthGrid({400, 410, 405}, "scan.hdr");
    FAIL();
  } catch (const specula::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("scan.hdr"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("405"), std::string::npos);
  }
}

TEST(AscendingBandOrder, SortsTheGivenBandsAndReportsARepeat) {
  const std::vector<double> nm = {600, 400, 650, 500};
  const auto never = [](std::size_t, std::size_t) { FAIL() << "no wavelength is repeated"; };
  EXPECT_EQ(specula::ascending_band_order(nm, never), (std::vector<std::size_t>{1, 3, 0, 2}));
  EXPECT_EQ(specula::ascending_band_order(nm, {0, 2, 3}, never), (std::vector<std::size_t>{3, 0, 2}));

  const std::vector<double> twice = {500, 400, 450, 400};
  std::size_t first = 0, second = 0;
  EXPECT_THROW(specula::ascending_band_order(twice,
                                             [&](std::size_t a, std::size_t b) {
                                               first = a, second = b;
                                               throw specula::InputError("repeated");
                                             }),
               specula::InputError);
  EXPECT_EQ(first, 1u);
  EXPECT_EQ(second, 3u);
  EXPECT_EQ(specula::ascending_band_order(twice, {0, 1, 2}, never), (std::vector<std::size_t>{1, 2, 0}));
  EXPECT_THROW(specula::ascending_band_order(twice, [](std::size_t, std::size_t) {}), specula::LibraryError);
}

TEST(Resample, LinearFunctionIsReproducedExactly) {
  auto from = WavelengthGrid::range(380, 780, 5);
  auto to = WavelengthGrid::range(420, 720, 10);
  Eigen::VectorXd s(from.size());
  for (std::size_t i = 0; i < from.size(); ++i) s[Eigen::Index(i)] = 0.5 + 0.002 * from[i];
  Eigen::VectorXd r = specula::resample_matrix(from, to) * s;
  for (std::size_t i = 0; i < to.size(); ++i) EXPECT_NEAR(r[Eigen::Index(i)], 0.5 + 0.002 * to[i], 1e-12);
  // irregular target between samples: linear interpolation of a linear function is exact
  auto odd = WavelengthGrid({381.25, 512.5, 777.7});
  Eigen::VectorXd r2 = specula::resample_matrix(from, odd) * s;
  for (std::size_t i = 0; i < odd.size(); ++i) EXPECT_NEAR(r2[Eigen::Index(i)], 0.5 + 0.002 * odd[i], 1e-12);
  // rows sum to one
  EXPECT_NEAR((specula::resample_matrix(from, odd).rowwise().sum().array() - 1).abs().maxCoeff(), 0, 1e-15);
}

TEST(Resample, RefusesExtrapolation) {
  auto from = WavelengthGrid::range(400, 700, 10);
  try {
    specula::resample_matrix(from, WavelengthGrid::range(380, 720, 10), "cave.png");
    FAIL();
  } catch (const specula::InputError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("cave.png"), std::string::npos);
    EXPECT_NE(m.find("380"), std::string::npos);
    EXPECT_NE(m.find("extrapolation"), std::string::npos);
  }
}

TEST(Trapezoid, IntegratesQuadraticOnIrregularGridToTrapezoidError) {
  auto g = WavelengthGrid({0.5, 1, 2, 2.5, 4});
  Eigen::VectorXd w = specula::trapezoid_weights(g);
  EXPECT_NEAR(w.sum(), 3.5, 1e-15);  // integral of 1
  Eigen::VectorXd x(5);
  x << 0.5, 1, 2, 2.5, 4;
  EXPECT_NEAR(w.dot(x), (16 - 0.25) / 2, 1e-12);  // integral of x is exact for the trapezoid rule
}

TEST(SampleTabulated, ZeroOutsideAndInterpolatesInside) {
  std::vector<double> x{400, 500, 600}, y{1, 3, 2};
  auto v = specula::sample_tabulated(x, y, WavelengthGrid({350, 400, 450, 600, 650}));
  EXPECT_EQ(v[0], 0);
  EXPECT_EQ(v[1], 1);
  EXPECT_DOUBLE_EQ(v[2], 2);
  EXPECT_EQ(v[3], 2);
  EXPECT_EQ(v[4], 0);
}

TEST(WavelengthGrid, NearestBandTakesTheLowerOfTwoAsNear) {
  const auto g = specula::WavelengthGrid::parse("450,500,600");
  EXPECT_EQ(g.nearest(300), 0u);
  EXPECT_EQ(g.nearest(474), 0u);
  EXPECT_EQ(g.nearest(475), 0u);  // 25 nm from 450 and from 500
  EXPECT_EQ(g.nearest(476), 1u);
  EXPECT_EQ(g.nearest(560), 2u);
  EXPECT_EQ(g.nearest(1e6), 2u);
  EXPECT_EQ(specula::WavelengthGrid().nearest(500), 0u);
}
