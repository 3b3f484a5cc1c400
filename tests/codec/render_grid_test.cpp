// render_sphere of a spectral grid under an illuminant: Lambert's cosine law, and the colour of a surface that
// reflects only long wavelengths.
#include <gtest/gtest.h>

#include <cmath>

#include "specula/codec/render.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/core/illuminant.h"

namespace specula::codec {
namespace {

store::Grid grid_of(const brdf::SpectralModel& model) {
  store::Grid g;
  g.wavelengths = model.wavelengths();
  g.brdf.resize(model.bands() * brdf::kMerlCells);
  brdf::evaluate_grid(model, g.brdf);
  return g;
}

TEST(RenderGrid, GreyLambertianUnderD65FollowsTheCosineLaw) {
  const WavelengthGrid wl = WavelengthGrid::range(400, 700, 10);
  const store::Grid g = grid_of(brdf::Lambertian(wl, Eigen::VectorXd::Constant(Eigen::Index(wl.size()), 0.4)));
  const Eigen::Vector3d light(0, 0, 1);
  const std::size_t size = 32;
  const SphereImage img = render_sphere(g, illuminant("D65", wl), size, light);
  std::size_t checked = 0;
  for (std::size_t row = 0; row < size; ++row)
    for (std::size_t col = 0; col < size; ++col) {
      const double x = (double(col) + 0.5) / double(size) * 2 - 1, y = 1 - (double(row) + 0.5) / double(size) * 2;
      const double nz = std::sqrt(std::max(0.0, 1 - x * x - y * y));
      const std::size_t p = row * size + col;
      if (!img.covered[p] || nz < 0.3) continue;
      // D65 is the white of linear sRGB: a grey surface is grey, rho * cos(theta_i) in every channel.
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.linear[3 * p + std::size_t(c)], 0.4 * nz, 1e-2) << row << " " << col;
      ++checked;
    }
  EXPECT_GT(checked, size * size / 3);
}

TEST(RenderGrid, ALongWavelengthReflectorIsRed) {
  const WavelengthGrid wl = WavelengthGrid::range(400, 700, 10);
  Eigen::VectorXd rho(Eigen::Index(wl.size()));
  for (std::size_t i = 0; i < wl.size(); ++i) rho[Eigen::Index(i)] = wl[i] >= 600 ? 0.8 : 0.0;
  const store::Grid g = grid_of(brdf::Lambertian(wl, rho));
  const SphereImage img = render_sphere(g, illuminant("D65", wl), 16, Eigen::Vector3d(0, 0, 1));
  const std::size_t p = 8 * 16 + 8;
  EXPECT_GT(img.linear[3 * p], 0.2f);
  EXPECT_LT(img.linear[3 * p + 1], 0.5f * img.linear[3 * p]);
  EXPECT_LT(img.linear[3 * p + 2], 0.5f * img.linear[3 * p]);
}

}  // namespace
}  // namespace specula::codec
