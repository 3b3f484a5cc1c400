// project_image against the formula x' = mean + ((x - mean) . v) v for a one-component PCA basis, evaluated here
// pixel by pixel, over an image taller than one row block, with masked pixels.
#include <gtest/gtest.h>

#include <random>

#include "specula/core/error.h"
#include "specula/stats/project.h"

using namespace specula;

TEST(ProjectImage, OneComponentByHandWithAMask) {
  const std::size_t h = 300, w = 1000, b = 4;  // 300 rows of 4000 values: several blocks of 2^20 doubles
  store::Cube cube;
  cube.height = h;
  cube.width = w;
  cube.bands = b;
  cube.wavelengths = WavelengthGrid::range(400, 430, 10);
  cube.data.resize(h * w * b);
  cube.mask.assign(h * w, 1);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : cube.data) v = u(rng);
  for (std::size_t p = 0; p < h * w; p += 7) cube.mask[p] = 0;
  store::Basis basis;
  basis.method = "pca";
  basis.wavelengths = cube.wavelengths;
  basis.mean = Eigen::Vector4d(0.5, 0.4, 0.3, 0.2);
  basis.components = Eigen::RowVector4d(0.5, 0.5, 0.5, 0.5);
  basis.eigenvalues = Eigen::VectorXd::Ones(1);
  const stats::Projector projector(basis, 1);
  std::vector<float> recon(cube.data.size(), -1.0f);
  const stats::ImageProjection r = stats::project_image(cube, projector, recon);
  EXPECT_EQ(r.k, 1u);
  double sum_sq = 0, max_error = 0;
  std::size_t valid = 0;
  for (std::size_t p = 0; p < h * w; ++p) {
    const float* x = cube.data.data() + p * b;
    if (!cube.mask[p]) {
      for (std::size_t k = 0; k < b; ++k) ASSERT_EQ(recon[p * b + k], 0.0f);
      ASSERT_EQ(r.error[p], 0.0f);
      continue;
    }
    double c = 0;
    for (std::size_t k = 0; k < b; ++k) c += (x[k] - basis.mean[Eigen::Index(k)]) * 0.5;
    double e2 = 0;
    for (std::size_t k = 0; k < b; ++k) {
      const double want = basis.mean[Eigen::Index(k)] + c * 0.5;
      ASSERT_NEAR(recon[p * b + k], want, 1e-6);
      e2 += (x[k] - want) * (x[k] - want);
    }
    ASSERT_NEAR(r.error[p], std::sqrt(e2), 1e-5);
    sum_sq += e2;
    max_error = std::max(max_error, std::sqrt(e2));
    ++valid;
  }
  EXPECT_NEAR(r.rms, std::sqrt(sum_sq / double(valid * b)), 1e-9);
  EXPECT_NEAR(r.max_error, max_error, 1e-9);
  std::vector<float> wrong(10);
  EXPECT_THROW(stats::project_image(cube, projector, wrong), UsageError);
}
