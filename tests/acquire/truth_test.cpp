// The truth metrics against closed forms: light directions rotated by known angles, and samples that are the model
// times a known factor.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "specula/acquire/truth.h"
#include "specula/core/brdf_materials.h"
#include "test_support.h"

using namespace specula;

TEST(Truth, LightDirectionErrorIsTheAngleToTheManifestsDirections) {
  acquire::Capture cap;
  cap.truth = acquire::CaptureTruth{};
  acquire::Calibration c;
  const double deg = std::numbers::pi / 180;
  for (double a : {1.0, 3.0}) {
    cap.truth->light_dirs.push_back({0, 0, 1});
    c.light_dirs.push_back(Eigen::Vector3d(std::sin(a * deg), 0, std::cos(a * deg)));
  }
  const auto [mean, worst] = acquire::light_direction_error(cap, c);
  EXPECT_NEAR(mean, 2.0, 1e-9);
  EXPECT_NEAR(worst, 3.0, 1e-9);
  cap.truth->light_dirs.pop_back();
  EXPECT_EQ(acquire::light_direction_error(cap, c).first, -1) << "a count mismatch has no meaningful error";
}

TEST(Truth, SampleErrorIsTheMedianRatioToTheModel) {
  test::ScratchDir dir;
  const WavelengthGrid wl = WavelengthGrid::range(450, 650, 50);
  const auto model = brdf::make_material("green-matte", wl);
  std::vector<double> angles;
  std::vector<float> values;
  std::vector<double> f(wl.size());
  for (int i = 0; i < 301; ++i) {
    const brdf::StdAngles a{0.01 * i, 0.3, 0.5, 2.0};
    model->eval(a, f);
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    for (double v : f) values.push_back(float(v * (i < 200 ? 1.1 : 0.5)));  // two thirds 10 % high: the median
  }
  {
    store::StoreWriter w(dir / "s.h5", {});
    w.create_samples("scan", wl, "1/sr", {});
    w.append_samples("scan", angles, values);
    w.commit();
  }
  const auto [err, ratio] = acquire::sample_error(store::Store::open(dir / "s.h5"), "scan", *model);
  EXPECT_NEAR(ratio, 1.1, 1e-6);
  EXPECT_NEAR(err, 0.1, 1e-6);
}
