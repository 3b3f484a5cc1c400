#include "specula/codec/render.h"

#include <gtest/gtest.h>

#include <cmath>

#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;

MerlBrdf merl_of(const brdf::SpectralModel& model) {
  store::Grid g;
  g.wavelengths = model.wavelengths();
  g.brdf.resize(model.bands() * N);
  brdf::evaluate_grid(model, g.brdf);
  return grid_to_merl(g, rgb_weights(g.wavelengths, illuminant("D65", g.wavelengths))).brdf;
}

Eigen::Vector3d normal_at(std::size_t size, std::size_t row, std::size_t col) {
  const double x = (double(col) + 0.5) / double(size) * 2 - 1, y = 1 - (double(row) + 0.5) / double(size) * 2;
  return {x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y))};
}

// Lambert's cosine law: a grey Lambertian sphere shows rho * max(0, n . l) wherever the cells hold data.
TEST(Render, LambertianSphereFollowsTheCosineLaw) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 50);
  const MerlBrdf m = merl_of(brdf::Lambertian(grid, Eigen::VectorXd::Constant(7, 0.5)));
  const Eigen::Vector3d light(-1, 1, 1);
  const std::size_t size = 64;
  const SphereImage img = render_sphere(m, size, light);
  std::size_t checked = 0, covered = 0;
  for (std::size_t row = 0; row < size; ++row)
    for (std::size_t col = 0; col < size; ++col) {
      const std::size_t p = row * size + col;
      const Eigen::Vector3d n = normal_at(size, row, col);
      const double x = (double(col) + 0.5) / double(size) * 2 - 1, y = 1 - (double(row) + 0.5) / double(size) * 2;
      ASSERT_EQ(img.covered[p], x * x + y * y < 1 ? 1 : 0);
      if (!img.covered[p]) {
        ASSERT_EQ(img.linear[3 * p], 0.0f);
        continue;
      }
      ++covered;
      const double cos_i = n.dot(light.normalized());
      if (cos_i < 0.2 || n.z() < 0.2) continue;  // cells near the horizon may hold no data
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(img.linear[3 * p + std::size_t(c)], 0.5 * cos_i, 1e-5) << row << " " << col;
      ++checked;
    }
  EXPECT_GT(checked, covered / 4);
  // The side away from the light (x = y = -0.6 mirrored: lower right, n . l < 0) is black but covered.
  ASSERT_EQ(img.covered[50 * size + 50], 1);
  ASSERT_LT(normal_at(size, 50, 50).dot(light.normalized()), 0.0);
  EXPECT_EQ(img.linear[3 * (50 * size + 50)], 0.0f);
}

// A sharp Ward lobe puts the highlight where the normal bisects the light and the viewer.
TEST(Render, WardHighlightSitsAtTheHalfVector) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 50);
  const MerlBrdf m = merl_of(brdf::Ward(grid, Eigen::VectorXd::Constant(7, 0.1), Eigen::VectorXd::Constant(7, 0.5),
                                        Eigen::VectorXd::Constant(7, 0.05)));
  const Eigen::Vector3d light(1, 0.5, 1);
  const std::size_t size = 128;
  const SphereImage img = render_sphere(m, size, light);
  std::size_t best = 0;
  for (std::size_t p = 0; p < size * size; ++p)
    if (img.linear[3 * p + 1] > img.linear[3 * best + 1]) best = p;
  const Eigen::Vector3d h = (light.normalized() + Eigen::Vector3d(0, 0, 1)).normalized();
  const Eigen::Vector3d n = normal_at(size, best / size, best % size);
  EXPECT_LT(std::acos(std::min(1.0, n.dot(h))), 0.05) << best / size << " " << best % size;
  EXPECT_THROW(render_sphere(m, 0, light), UsageError);
  EXPECT_THROW(render_sphere(m, 16, Eigen::Vector3d::Zero()), UsageError);
}

}  // namespace
}  // namespace specula::codec
