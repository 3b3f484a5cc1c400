// The retro band's trend (acquire/retro_trend.h): the exponent a tally learns from grids whose every column's ln v is
// exactly a line in theta_d^p is p (a line through exact points is the line), whatever the rows below theta_h row 10
// or the columns without data at retro-reflection hold; adding the rows in pieces sums the same; sizes are checked.
#include "specula/acquire/retro_trend.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;

// channels x 90 theta_h rows x kRow values: ln v = a_k - 0.01 theta_h + slope(phi_d) (theta_d + 0.5)^p, p = `inner`
// below theta_h row 10 and `p` from it on; with `holes`, every 4th column has 0 at theta_d row 0 and the exponent 1.
std::vector<float> grid_of(std::size_t channels, double p, double inner, bool holes) {
  std::vector<float> v(channels * brdf::kMerlThetaH * kRow, -1.0f);
  for (std::size_t k = 0; k < channels; ++k)
    for (int h = 0; h < brdf::kMerlThetaH; ++h)
      for (int d = 0; d < brdf::kMerlThetaD; ++d)
        for (int f = 0; f < brdf::kMerlPhiD; ++f) {
          const bool hole = holes && f % 4 == 0;
          const double q = hole ? 1.0 : h < 10 ? inner : p, slope = 0.002 + 0.0001 * (f % 7);
          v[(k * brdf::kMerlThetaH + std::size_t(h)) * kRow + std::size_t(d * brdf::kMerlPhiD + f)] =
              hole && d == 0 ? 0.0f : float(std::exp(-2.0 + 0.3 * double(k) - 0.01 * h + slope * std::pow(d + 0.5, q)));
        }
  return v;
}

std::size_t candidate(double p) {
  const auto c = retro_exponent_candidates();
  return std::size_t(std::ranges::find(c, p) - c.begin());
}

TEST(RetroTrend, TheExponentLearnedIsTheOneTheColumnsAreLinesIn) {
  for (const double p : {1.3, 2.0, 1.0}) {
    RetroExponentTally tally;
    tally.add(grid_of(2, p, p == 1.0 ? 2.0 : 1.0, true), 2, 0, brdf::kMerlThetaH);
    const std::vector<double> e = tally.exponents();
    ASSERT_EQ(e.size(), std::size_t(kRetroLearnedRows));
    EXPECT_EQ(e[0], 2.0) << "one row above the band gives a flat line whatever the exponent: a tie";
    for (int b = 2; b <= kRetroLearnedRows; ++b) {
      EXPECT_EQ(e[std::size_t(b - 1)], p) << "width " << b;
      EXPECT_LT(tally.mean_error(b, candidate(p)), 1e-12) << "width " << b;
      EXPECT_GT(tally.mean_error(b, candidate(p == 1.0 ? 2.0 : 1.0)), 1e-6) << "width " << b;
    }
  }
}

TEST(RetroTrend, RowsAddedInPiecesSumAsAtOnce) {
  const std::vector<float> v = grid_of(3, 1.5, 1.5, false);
  std::vector<float> mixed = v;  // columns with other exponents, so that every candidate has an error
  for (std::size_t i = 0; i < mixed.size(); i += 7) mixed[i] *= 1.01f;
  RetroExponentTally whole, pieces;
  whole.add(mixed, 3, 0, brdf::kMerlThetaH);
  for (const auto& [h0, rows] : {std::pair<std::size_t, std::size_t>{0, 37}, {37, 1}, {38, 52}}) {
    std::vector<float> part(3 * rows * kRow);
    for (std::size_t k = 0; k < 3; ++k)
      std::copy_n(mixed.begin() + std::ptrdiff_t((k * brdf::kMerlThetaH + h0) * kRow), rows * kRow,
                  part.begin() + std::ptrdiff_t(k * rows * kRow));
    pieces.add(part, 3, h0, rows);
  }
  for (int b = 1; b <= kRetroLearnedRows; ++b)
    for (std::size_t c = 0; c < retro_exponent_candidates().size(); ++c)
      EXPECT_EQ(whole.mean_error(b, c), pieces.mean_error(b, c)) << "width " << b << " candidate " << c;
  EXPECT_EQ(whole.exponents(), pieces.exponents());
}

TEST(RetroTrend, ATableGivesEachWidthItsExponentAndAnEmptyOneTwo) {
  const std::vector<double> table = {1.1, 1.4, 1.7};
  EXPECT_EQ(retro_exponent(table, 1), 1.1);
  EXPECT_EQ(retro_exponent(table, 3), 1.7);
  EXPECT_EQ(retro_exponent(table, 9), 1.7);
  EXPECT_EQ(retro_exponent({}, 5), 2.0);
  EXPECT_DOUBLE_EQ(retro_abscissa(3, 1.5), std::pow(3.5, 1.5));
}

TEST(RetroTrend, SizesAndRowsAreChecked) {
  RetroExponentTally tally;
  std::vector<float> v(2 * kRow, 1.0f);
  EXPECT_THROW(tally.add(v, 2, 0, 2), UsageError);
  EXPECT_THROW(tally.add(v, 2, 90, 1), UsageError);
  EXPECT_THROW(tally.add(v, 0, 0, 1), UsageError);
  EXPECT_THROW(tally.mean_error(0, 0), UsageError);
  EXPECT_THROW(tally.mean_error(1, retro_exponent_candidates().size()), UsageError);
  const std::vector<double> x = {1, 2}, y = {1};
  EXPECT_THROW(shrunk_line(x, y), UsageError);
}

}  // namespace
}  // namespace specula::acquire
