#include "specula/core/relight.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

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
  const Relighting r = relight(f, kGrid, SpectrumKind::reflectance, {}, illuminant("D65", kGrid), illuminant("A", kGrid));
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
