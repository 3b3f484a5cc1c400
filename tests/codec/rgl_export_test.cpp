// Export of MERL-layout BRDFs to RGL files: the microfacet pieces against closed forms, and export -> import round
// trips of analytic grids judged by the lighting suite (codec/suite.h, what brdf-diff reports; the fidelity goal of
// issue 26).
#include "specula/codec/rgl_export.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "grid_fixture.h"
#include "specula/codec/diff.h"
#include "specula/codec/environment.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(RglExport, SigmaOfTheCosineDistributionIsItsClosedForm) {
  // D = 1/pi: sigma(theta) = (1/pi) * pi (1 + cos theta) / 2.
  const std::vector<double> d(128, 1 / kPi);
  const std::vector<double> theta = {0, 0.3, 0.8, 1.2, kPi / 2};
  const auto s = rgl_sigma(d, theta);
  for (std::size_t k = 0; k < theta.size(); ++k) EXPECT_NEAR(s[k], (1 + std::cos(theta[k])) / 2, 2e-4) << theta[k];
}

TEST(RglExport, PowerIterationRecoversABeckmannDistributionFromItsRetroReflection) {
  // Retro-reflection of a Beckmann microfacet BRDF with Smith masking, G(k, k) = G1(k) = cos / sigma (Dupuy et al.
  // 2015): f(k, k) = F D(k) / (4 sigma(k) cos(k)). The iteration must give D back, normalised to sigma(0) = 1.
  const std::size_t n = 128;
  const double alpha = 0.3;
  std::vector<double> truth(n), theta(n);
  for (std::size_t k = 0; k < n; ++k) {
    theta[k] = rgl_u_to_theta(double(k) / double(n - 1));
    const double c = std::cos(theta[k]), t2 = std::tan(theta[k]) * std::tan(theta[k]);
    truth[k] = k + 1 == n ? 0 : std::exp(-t2 / (alpha * alpha)) / (kPi * alpha * alpha * c * c * c * c);
  }
  const auto sigma = rgl_sigma(truth, theta);
  std::vector<double> retro(n);
  for (std::size_t k = 0; k < n; ++k) retro[k] = k + 1 == n ? 0 : 0.04 * truth[k] / (4 * sigma[k] * std::cos(theta[k]));
  const auto d = rgl_ndf_from_retro(retro, 30);
  EXPECT_NEAR(sigma[0], 1.0, 2e-3);  // the analytic D is normalised: the quadrature agrees
  for (std::size_t k = 0; k < n; ++k)
    if (truth[k] > 1e-3 * truth[0]) {
      EXPECT_NEAR(d[k] / truth[k], 1.0 / sigma[0], 0.01) << "theta " << theta[k];
    }
}

store::Grid material(const std::string& name) { return test::grid_of(*brdf::make_material(name, test::kCodecBands)); }

TEST(RglExport, TheFileIsWhatTheRenderersCheck) {
  const RglBsdf b = export_rgl(material("blue-paint"), {});
  EXPECT_EQ(b.theta_i.size(), 8u);
  EXPECT_FLOAT_EQ(b.theta_i.front(), 0.0f);
  EXPECT_FLOAT_EQ(b.theta_i.back(), float(kPi / 2));
  EXPECT_EQ(b.wavelengths.size(), test::kCodecBands.size());
  EXPECT_NEAR(b.sigma[0], 1.0f, 1e-6);
  // Uniform in sigma: sigma at the theta_i nodes steps evenly (read from the table linearly in u).
  const RglEvaluator e(b);
  const double s0 = e.sigma(0), s7 = e.sigma(b.theta_i[7]);
  for (std::size_t j = 1; j < 7; ++j) EXPECT_NEAR(e.sigma(b.theta_i[j]), s0 - double(j) / 7 * (s0 - s7), 1e-4);
  const RglBsdf back = from_tensor(to_tensor(b), "x.bsdf");
  EXPECT_EQ(back.values, b.values);
  EXPECT_EQ(back.vndf, b.vndf);
  EXPECT_EQ(back.wavelengths, b.wavelengths);
  EXPECT_EQ(back.valid, b.valid);
  const auto bytes = tensor_file_bytes(to_tensor(b));
  EXPECT_LE(bytes.size(), 8u * 7 * 32 * 32 * 4 + 80000);
}

struct Trip {
  const char* material;
  std::size_t resolution;  // the sample grid: the default 32, or what the material needs to meet the goal
  // Tighter than the goal (0.5, 1.5): what the default export keeps with its values fitted by least squares (0.045
  // to 0.13 mean, 0.20 to 0.48 p95); point samples at the nodes gave 0.14 to 0.29 and 0.64 to 0.92.
  double mean = 0.16, p95 = 0.6;
};
class RoundTrip : public ::testing::TestWithParam<Trip> {};

TEST_P(RoundTrip, ExportThenImportIsWithinTheFidelityGoal) {
  const store::Grid a = material(GetParam().material);
  const store::Grid b = rgl_to_grid(export_rgl(a, {.resolution = GetParam().resolution}), "trip.bsdf");
  static const LightingSuite suite(a.wavelengths);
  const SuiteDiff d = suite_diff(a, b, suite);
  RecordProperty("de00_mean", std::to_string(d.de00_mean));
  RecordProperty("de00_p95", std::to_string(d.de00_p95));
  std::printf("%s: suite dE00 mean %.3f p95 %.3f max %.3f, rel_rms_cos %.4f\n", GetParam().material, d.de00_mean,
              d.de00_p95, d.de00_max, d.rel_rms_cos);
  EXPECT_LE(d.de00_mean, GetParam().mean);
  EXPECT_LE(d.de00_p95, GetParam().p95);
}

INSTANTIATE_TEST_SUITE_P(Analytic, RoundTrip,
                         ::testing::Values(Trip{"green-matte", 32}, Trip{"blue-paint", 32}, Trip{"red-plastic", 32},
                                           Trip{"gold", 32}, Trip{"cyan-gloss", 32}),
                         [](const auto& info) {
                           std::string n = info.param.material;
                           for (auto& c : n)
                             if (c == '-') c = '_';
                           return n;
                         });

TEST(RglExport, RgbExportOfAMerlBrdfRoundTrips) {
  const store::Grid a = material("red-plastic");
  const MerlBrdf rgb = grid_to_merl(a, rgb_weights(a.wavelengths, illuminant("D65", a.wavelengths))).brdf;
  const RglBsdf b = export_rgl(rgb, {});
  EXPECT_TRUE(b.rgb);
  const MerlBrdf back = rgl_to_merl(b);
  // The median relative error over the cells whose directions both lie within 80 degrees of the normal.
  std::vector<double> rel;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 7) {
    if (!rgb.has_data(cell) || !back.has_data(cell)) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
    if (wi.z() < 0.17 || wo.z() < 0.17) continue;
    for (int c = 0; c < 3; ++c)
      if (rgb.value(c, cell) > 1e-3) rel.push_back(std::abs(back.value(c, cell) / rgb.value(c, cell) - 1));
  }
  ASSERT_GT(rel.size(), 1000u);
  std::nth_element(rel.begin(), rel.begin() + std::ptrdiff_t(rel.size() / 2), rel.end());
  std::printf("RGB red-plastic: median relative error %.4f over %zu values\n", rel[rel.size() / 2], rel.size());
  EXPECT_LT(rel[rel.size() / 2], 0.05);
}

TEST(RglExport, SettingsOutOfRangeAreRefused) {
  EXPECT_THROW(export_rgl(material("green-matte"), {.theta_i = 1}), UsageError);
  EXPECT_THROW(export_rgl(material("green-matte"), {.resolution = 1}), UsageError);
  EXPECT_THROW(export_rgl(material("green-matte"), {.vndf_exponent = 0}), UsageError);
}

}  // namespace
}  // namespace specula::codec
