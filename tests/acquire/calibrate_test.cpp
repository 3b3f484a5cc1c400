// Geometric and spatial calibration against a simulated capture's truth: the silhouette's circle within 0.25 px,
// the sphere's centre within 0.5 %, light directions within 0.25 degrees, S(x, y) against the simulator's
// vignetting; and Nelder-Mead on a closed-form minimum.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "small_rig.h"
#include "specula/acquire/calibrate.h"
#include "specula/acquire/capture.h"
#include "specula/acquire/pipeline.h"
#include "specula/acquire/simulate.h"
#include "specula/store/io/png_stack.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;
using std::numbers::pi;

namespace {

GreyImage load(const std::filesystem::path& p) {
  const store::PngImage png = store::read_png(p);
  GreyImage g{int(png.width), int(png.height), std::vector<float>(png.samples.begin(), png.samples.end())};
  return g;
}

struct Simulated {
  test::ScratchDir dir;
  Capture cap;
  Pinhole camera;
  Sphere truth;
  explicit Simulated(bool noise, double sphere_px = 90) {
    // Up to 135 degrees: beyond, the mirror highlight leaves the visible sphere.
    SimulatorOptions o = test::small_rig(128, sphere_px, 6, 25, {500, 600}, noise);
    o.exposures_s = {0.01, 0.1};
    cap = simulate_capture(o, dir / "cap");
    camera = {cap.focal_px, cap.cx, cap.cy};
    truth = {Eigen::Vector3d(cap.truth->sphere_centre[0], cap.truth->sphere_centre[1], cap.truth->sphere_centre[2]),
             cap.truth->sphere_radius};
  }
  // The traced silhouette's centroid and equivalent radius, 16 x 16 samples per pixel.
  Circle truth_circle() const {
    double area = 0, sx = 0, sy = 0, t;
    for (int v = 0; v < cap.height; ++v)
      for (int u = 0; u < cap.width; ++u)
        for (int j = 0; j < 16; ++j)
          for (int i = 0; i < 16; ++i) {
            const double x = u + (i + 0.5) / 16, y = v + (j + 0.5) / 16;
            if (truth.hit(camera.ray(x, y), t)) area += 1.0 / 256, sx += x / 256, sy += y / 256;
          }
    return {sx / area, sy / area, std::sqrt(area / pi)};
  }
};

TEST(NelderMead, FindsTheMinimumOfARotatedQuadratic) {
  auto f = [](const Eigen::VectorXd& x) {
    const double a = x[0] - 1.5, b = x[1] + 0.25, c = x[2] - 3;
    return 2 * a * a + b * b + 0.5 * c * c + 0.8 * a * b + 7;
  };
  const SimplexResult r = nelder_mead(f, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1));
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.x[0], 1.5, 1e-4);
  EXPECT_NEAR(r.x[1], -0.25, 1e-4);
  EXPECT_NEAR(r.x[2], 3, 1e-4);
  EXPECT_NEAR(r.value, 7, 1e-8);
}

TEST(Calibrate, CircleSphereAndLightsMatchTheTruth) {
  for (const bool noise : {false, true}) {
    const Simulated s(noise);
    const Circle want = s.truth_circle();
    const GreyImage sil = load(s.dir / "cap" / "silhouette.png");
    const Circle c = detect_circle(sil);
    EXPECT_NEAR(c.cx, want.cx, 0.25) << "noise " << noise;
    EXPECT_NEAR(c.cy, want.cy, 0.25) << "noise " << noise;
    EXPECT_NEAR(c.r, want.r, 0.25) << "noise " << noise;

    const Sphere sphere = fit_sphere(c, s.camera, s.cap.sphere_radius_m, s.cap.width, s.cap.height);
    EXPECT_LT((sphere.centre - s.truth.centre).norm(), 0.005 * s.truth.centre.norm()) << sphere.centre.transpose();
    EXPECT_DOUBLE_EQ(sphere.radius, s.truth.radius);

    // Each mirror highlight alone, then every light from the arc fitted through them (the arc's angles are known).
    std::vector<Eigen::Vector3d> measured, truth;
    std::vector<double> weights;
    for (const auto& im : s.cap.images) {
      if (im.kind != ImageKind::mirror) continue;
      double w = 0;
      measured.push_back(light_direction(load(s.dir / "cap" / im.file), s.camera, sphere, s.cap.light_distance_m, &w));
      weights.push_back(w * w);
      const auto& t = s.cap.truth->light_dirs[std::size_t(im.light)];
      truth.emplace_back(t[0], t[1], t[2]);
    }
    ASSERT_EQ(measured.size(), 6u);
    auto degrees = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / pi;
    };
    EXPECT_LT(degrees(measured[0], truth[0]), 0.25);  // facing the camera, a single highlight is already this good
    const std::vector<Eigen::Vector3d> arc = fit_light_arc(measured, weights, s.cap.light_angles_deg);
    for (std::size_t l = 0; l < arc.size(); ++l)
      EXPECT_LT(degrees(arc[l], truth[l]), 0.25) << "light " << l << " noise " << noise;
    // The arc also places a light whose highlight was not used.
    std::vector<double> without = weights;
    without[5] = 0;
    EXPECT_LT(degrees(fit_light_arc(measured, without, s.cap.light_angles_deg)[5], truth[5]), 0.25);
  }
}

TEST(Calibrate, SpatialResponseIsTheVignetting) {
  const Simulated s(true);
  // Each band's flat exposures merged (the slope drops the sensor's bias).
  std::vector<GreyImage> flats;
  for (int b = 0; b < 2; ++b) {
    const HdrImage h = merge_series(s.cap, s.dir / "cap", ImageKind::flat, -1, -1, b, {});
    flats.push_back({s.cap.width, s.cap.height, h.rate});
  }
  ASSERT_EQ(flats.size(), 2u);
  const GreyImage S = spatial_response(flats);
  // The simulator's S = 1 - 0.25 r^2 / 2, r normalised to the half-size, divided by its central mean.
  auto model = [&](int u, int v) {
    const double dx = (u + 0.5 - 64) / 64, dy = (v + 0.5 - 64) / 64;
    return 1 - 0.25 * (dx * dx + dy * dy) / 2;
  };
  double centre = 0;
  int n = 0;
  const double half = std::sqrt(0.05) / 2;
  for (int v = int((0.5 - half) * 128); v < int((0.5 + half) * 128); ++v)
    for (int u = int((0.5 - half) * 128); u < int((0.5 + half) * 128); ++u) centre += model(u, v), ++n;
  centre /= n;
  for (const auto& [u, v] : {std::pair{0, 0}, {127, 0}, {64, 64}, {10, 100}, {127, 127}})
    EXPECT_NEAR(S.at(u, v), model(u, v) / centre, 0.005) << u << "," << v;
}

TEST(Calibrate, ImagesWithoutASphereOrHighlightAreRefused) {
  GreyImage flat{64, 64, std::vector<float>(64 * 64, 3000.0f)};
  EXPECT_THROW(detect_circle(flat), InputError);
  const Sphere sphere{Eigen::Vector3d(0, 0, 1), 0.01};
  const Pinhole camera{2000, 32, 32};
  GreyImage dark{64, 64, std::vector<float>(64 * 64, 8.0f)};
  EXPECT_THROW(light_direction(dark, camera, sphere, 1.0), InputError);
}

}  // namespace
