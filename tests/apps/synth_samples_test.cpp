// synth-samples with a grid as the material: the samples of an analytic material's grid agree with the samples of
// the analytic material itself within the grid's discretisation (trilinear closer than the nearest cell); a bad
// lookup is one line. The sphere's image row decides how close to the specular peak the rig samples.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula {
namespace {

using test::run_specula;

// Relative L1 distance sum |a - b| / sum b between the values of two sample sets of the same size.
double relative_l1(const std::filesystem::path& db, const std::string& a, const std::string& b) {
  const auto s = store::Store::open(db);
  const std::size_t n = s.samples_info(b).size, bands = s.samples_info(b).bands;
  EXPECT_EQ(s.samples_info(a).size, n);
  std::vector<double> angles(4 * n);
  std::vector<float> va(n * bands), vb(n * bands);
  s.read_samples(a, 0, n, angles, va);
  s.read_samples(b, 0, n, angles, vb);
  double d = 0, sum = 0;
  for (std::size_t i = 0; i < va.size(); ++i) d += std::abs(double(va[i]) - vb[i]), sum += vb[i];
  return d / sum;
}

TEST(SynthSamplesCli, AGridMaterialGivesTheAnalyticModelsSamplesWithinItsDiscretisation) {
  test::ScratchDir dir;
  const auto db = dir / "s.h5";
  auto q = [](const std::filesystem::path& p) { return "'" + p.string() + "'"; };
  auto r = run_specula("synth-brdf study-ts --wavelengths 500:600:50 -o " + q(dir / "ts.spgrid"));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string common = " --sphere-px 40 --lights 30 --light-step 5 --wavelengths 500:600:50 -o " + q(db);
  for (const auto& [material, name] : {std::pair{std::string("study-ts"), "truth"},
                                       {q(dir / "ts.spgrid"), "tri"},
                                       {q(dir / "ts.spgrid") + " --lookup nearest", "near"}}) {
    r = run_specula("synth-samples " + material + common + ":" + name);
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const double tri = relative_l1(db, "tri", "truth"), near = relative_l1(db, "near", "truth");
  EXPECT_LT(tri, 0.004);  // measured 0.0023, the nearest cell 0.035
  EXPECT_LT(tri, near / 10) << "nearest " << near;
  r = run_specula("synth-samples " + q(dir / "ts.spgrid") + " --lookup cubic" + common + ":bad");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--lookup 'cubic'"), std::string::npos) << r.output;
}

// The smallest theta_h (degrees) over samples `name` of db.
double least_theta_h(const std::filesystem::path& db, const std::string& name) {
  const auto s = store::Store::open(db);
  const std::size_t n = s.samples_info(name).size, bands = s.samples_info(name).bands;
  std::vector<double> angles(4 * n);
  std::vector<float> values(n * bands);
  s.read_samples(name, 0, n, angles, values);
  double least = 90;
  for (std::size_t i = 0; i < n; ++i) {
    const brdf::StdAngles a{angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]};
    least = std::min(least, brdf::half_diff(a).theta_h * 180 / std::numbers::pi);
  }
  return least;
}

// The default rig images the sphere's centre on a row boundary (22 px), and the specular path, in the arc's plane,
// runs along it: every pixel centre lies half a pixel off it, 0.29 degrees of normal on a 200-pixel sphere, so no
// sample comes nearer the peak (MERL theta_h rows 0-4 stay empty). Moved half a pixel, the path runs through pixel
// centres and the peak is sampled.
TEST(SynthSamplesCli, TheSpheresImageRowDecidesHowNearThePeakTheScanSamples) {
  test::ScratchDir dir;
  const auto db = dir / "s.h5";
  const std::string common = " --lights 40 --light-step 4 --wavelengths 500:600:100 -o '" + db.string() + "':";
  auto r = run_specula("synth-samples green-matte" + common + "default");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("synth-samples green-matte --sphere-row 22.5" + common + "centred");
  ASSERT_EQ(r.status, 0) << r.output;
  const double half_pixel = 0.5 / 100 * 180 / std::numbers::pi;  // of normal, at the centre of a 200-pixel sphere
  EXPECT_GT(least_theta_h(db, "default"), 0.9 * half_pixel);
  EXPECT_LT(least_theta_h(db, "centred"), 0.2 * half_pixel);
  r = run_specula("synth-samples green-matte --sphere-row nan" + common + "bad");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--sphere-row"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace specula
