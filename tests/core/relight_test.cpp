#include "specula/core/relight.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <vector>

#include "quadrature_support.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula {
namespace {

const WavelengthGrid kGrid = WavelengthGrid::range(400, 700, 10);

// Rows: three neutral greys, then a narrow green band and a saturated red ramp.
RowMatrixXf spectra() {
  const Eigen::Index b = Eigen::Index(kGrid.size());
  RowMatrixXf s(5, b);
  s.row(0).setConstant(0.2f);
  s.row(1).setConstant(0.5f);
  s.row(2).setConstant(0.9f);
  s.row(3).setConstant(0.02f);
  s(3, 13) = 0.9f;  // 530 nm
  for (Eigen::Index i = 0; i < b; ++i) s(4, i) = float(i) / float(b - 1);
  return s;
}

TEST(Relight, SameLightChangesNothing) {
  const Eigen::VectorXd d65 = illuminant("D65", kGrid);
  const RowMatrixXf f = spectra();
  const Relighting r = relight(f, kGrid, SpectrumKind::reflectance, {}, d65, d65);
  EXPECT_LT((r.spectral - r.original).cwiseAbs().maxCoeff(), 1e-5f);
  EXPECT_LT((r.rgb - r.original).cwiseAbs().maxCoeff(), 1e-4f);
  EXPECT_LT(r.max_ciede2000, 1e-2);
}

TEST(Relight, VonKriesIsExactForGreysAndNotForSaturatedColours) {
  const RowMatrixXf f = spectra();
  const Relighting r =
      relight(f, kGrid, SpectrumKind::reflectance, {}, illuminant("D65", kGrid), illuminant("A", kGrid));
  // A grey reflectance c has XYZ c * white under any light, and eq 4.10 scales each channel by exactly that.
  for (Eigen::Index i = 0; i < 3; ++i) {
    EXPECT_LT(r.ciede2000[std::size_t(i)], 1e-3) << i;
    const float c = f(i, 0);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.spectral(i, k), c * r.white_to[k], 1e-4) << i;
  }
  EXPECT_GT(r.ciede2000[3], 0.5);
  EXPECT_EQ(r.pixels, 5u);
  EXPECT_NEAR(r.max_ciede2000, std::max(r.ciede2000[3], r.ciede2000[4]), 1e-12);
}

TEST(Relight, RadianceIsDividedByTheOldLight) {
  // Radiance = reflectance * D65, relit to A, is the reflectance relit, after the radiance's normalisation (its
  // 99th-percentile Y under the old light called 1), which scales every pixel by one factor s.
  const Eigen::VectorXd d65 = illuminant("D65", kGrid), a = illuminant("A", kGrid);
  const RowMatrixXf f = spectra();
  const RowMatrixXf radiance = f.array().rowwise() * d65.transpose().cast<float>().array();
  const Relighting from_radiance = relight(radiance, kGrid, SpectrumKind::radiance, {}, d65, a);
  const float s = from_radiance.original(2, 1) / 0.9f;  // the grey 0.9 has Y = 0.9 s
  // Of the five Y values the quantile picks the fourth smallest (index floor(0.99 * 4) = 3): it becomes 1.
  std::vector<float> y;
  for (Eigen::Index i = 0; i < 5; ++i) y.push_back(from_radiance.original(i, 1));
  std::sort(y.begin(), y.end());
  EXPECT_NEAR(y[3], 1.0f, 1e-5f);
  const RowMatrixXf scaled = f * s;
  const Relighting from_reflectance = relight(scaled, kGrid, SpectrumKind::reflectance, {}, d65, a);
  EXPECT_LT((from_radiance.spectral - from_reflectance.spectral).cwiseAbs().maxCoeff(), 1e-5f);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_NEAR(from_radiance.ciede2000[i], from_reflectance.ciede2000[i], 1e-3) << i;
}

// Eqs 4.9 and 4.10 on an irregular grid (spacings 3 to 20 nm) are their integrals by the trapezoid rule on the
// actual band centres, within its error bound of the direct integrals over the 1 nm CMF table:
// spectral = XYZ of r L_to / Y of L_to; the camera sees M * integral of cmf r L_from, scaled per channel by
// (M * integral of cmf L_to) / (M * integral of cmf L_from), divided by Y of L_to, and taken back to XYZ by M^-1.
TEST(Relight, OnAnIrregularGridBothRelightingsAreTheDirectIntegrals) {
  const WavelengthGrid grid = test::irregular_grid();
  const test::Spectrum r = [](double l) { return 0.3 + 0.25 * std::sin((l - 420) / 40) + 0.1 * std::cos(l / 17); };
  const test::Spectrum from = [](double l) { return 0.4 + 0.6 * (l - 400) / 300; };  // reddish, like A
  const test::Spectrum to = [](double l) { return 1.2 - 0.5 * (l - 400) / 300 + 0.1 * std::sin(l / 25); };
  const Eigen::Index b = Eigen::Index(grid.size());
  RowMatrixXf spectra(1, b);
  Eigen::VectorXd from_g(b), to_g(b);
  for (Eigen::Index i = 0; i < b; ++i) {
    spectra(0, i) = float(r(grid[std::size_t(i)]));
    from_g[i] = from(grid[std::size_t(i)]);
    to_g[i] = to(grid[std::size_t(i)]);
  }
  const Relighting got = relight(spectra, grid, SpectrumKind::reflectance, {}, from_g, to_g);

  // Integrals: 0-2 cmf r from, 3-5 cmf r to, 6-8 cmf from, 9-11 cmf to, 12 ybar.
  std::vector<test::Spectrum> f;
  for (const auto& g : std::vector<test::Spectrum>{[&](double l) { return r(l) * from(l); },
                                                   [&](double l) { return r(l) * to(l); }, from, to})
    for (int c = 0; c < 3; ++c) f.push_back([g, c](double l) { return test::cmf_at(c, l) * g(l); });
  f.push_back([](double l) { return test::cmf_at(1, l); });
  const Eigen::Matrix3d m = xyz_to_linear_srgb();
  const auto formula = [&](const std::vector<double>& i) {
    const auto v = [&](std::size_t k) { return Eigen::Vector3d(i[k], i[k + 1], i[k + 2]); };
    const Eigen::Vector3d gain = (m * v(9)).cwiseQuotient(m * v(6)) / (i[10] / i[12]);
    const Eigen::Vector3d rgb = m.inverse() * gain.asDiagonal() * m * v(0) / i[12];
    Eigen::VectorXd out(9);
    for (int c = 0; c < 3; ++c) {
      out[c] = i[std::size_t(c)] / i[7];
      out[3 + c] = i[std::size_t(3 + c)] / i[10];
      out[6 + c] = rgb[c];
    }
    return out;
  };
  const test::Propagated want = test::propagate(f, grid, formula);
  Eigen::VectorXd have(9);
  for (int c = 0; c < 3; ++c) {
    have[c] = got.original(0, c);
    have[3 + c] = got.spectral(0, c);
    have[6 + c] = got.rgb(0, c);
  }
  test::expect_integrals(have, want, 1e-6);
}

TEST(Relight, Misuse) {
  const Eigen::VectorXd d65 = illuminant("D65", kGrid);
  Eigen::VectorXd dark = d65;
  dark[3] = 0;
  const RowMatrixXf f = spectra();
  try {
    relight(f, kGrid, SpectrumKind::radiance, {}, dark, d65);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("430 nm"), std::string::npos) << e.what();
  }
  const std::vector<std::uint8_t> none(5, 0);
  EXPECT_THROW(relight(f, kGrid, SpectrumKind::reflectance, none, d65, d65), InputError);
  EXPECT_THROW(relight(f, kGrid, SpectrumKind::reflectance, std::vector<std::uint8_t>(4, 1), d65, d65), UsageError);
  EXPECT_THROW(relight(f, kGrid, SpectrumKind::reflectance, {}, d65.head(5), d65), UsageError);
}

}  // namespace
}  // namespace specula
