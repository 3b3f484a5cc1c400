#include "specula/stats/coefficients.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/QR>
#include <cmath>
#include <random>
#include <vector>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::stats {
namespace {

constexpr std::size_t kB = 12;

const WavelengthGrid& grid() {
  static const WavelengthGrid g = WavelengthGrid::range(400, 400 + 20 * double(kB - 1), 20);
  return g;
}

// Random spectra in [0, 1), every 7th pixel masked.
store::Cube image(std::size_t h, std::size_t w, unsigned seed) {
  store::Cube c;
  c.resize(h, w, kB);
  c.wavelengths = grid();
  c.units = "reflectance";
  c.mask.assign(h * w, 1);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  for (float& v : c.data) v = u(rng);
  for (std::size_t p = 3; p < h * w; p += 7) c.mask[p] = 0;
  return c;
}

// A PCA basis of 4 orthonormal components and a mean.
store::Basis pca_basis() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::MatrixXd r(kB, kB);
  for (Eigen::Index i = 0; i < r.size(); ++i) r.data()[i] = u(rng);
  store::Basis b;
  b.method = "pca";
  b.wavelengths = grid();
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(r).householderQ();
  b.components = q.leftCols(4).transpose();
  b.mean = Eigen::VectorXd::Constant(Eigen::Index(kB), 0.5);
  b.n = 1;
  return b;
}

struct Fixture {
  test::ScratchDir dir;
  std::filesystem::path db = dir / "db.h5";
  store::Cube a = image(40, 9, 1), b = image(23, 31, 2);
  Fixture() {
    store::StoreWriter w(db, {});
    w.add_image("a", a);
    w.add_image("b", b);
    w.add_basis("pca", pca_basis());
    w.commit();
  }
  // Writes the maps of both images into `out` (another store) and returns what the library reported.
  std::vector<CoefficientMap> write(const std::filesystem::path& out, std::size_t min_block_pixels = 64) const {
    const store::Store s = store::Store::open(db);
    const Projector projector(s.read_basis("pca"), 3, "pca");
    const store::BlockReader reader(s, {.image_globs = {"*"}}, min_block_pixels);
    const std::vector<std::string> names = {"a.pca", "b.pca"};
    store::StoreWriter w(out, {});
    auto maps = write_coefficient_maps(s, reader, projector, names, {.basis_name = "pca", .provenance = {}}, w);
    w.commit();
    return maps;
  }
};

// Every valid pixel's coefficients are (x - mean) V_3^T computed here, masked pixels 0 and masked in the map,
// and the reported error is that of the reconstruction from those coefficients.
TEST(CoefficientMaps, AreTheCentredProjectionOfEveryValidPixel) {
  Fixture f;
  const auto maps = f.write(f.dir / "out.h5");
  ASSERT_EQ(maps.size(), 2u);
  const store::Basis basis = pca_basis();
  const Eigen::MatrixXd v = basis.components.topRows(3);
  const store::Store out = store::Store::open(f.dir / "out.h5");
  for (const auto& [m, cube] : {std::pair{maps[0], &f.a}, std::pair{maps[1], &f.b}}) {
    EXPECT_EQ(m.height, cube->height);
    EXPECT_EQ(m.width, cube->width);
    const store::CoefficientsInfo info = out.coefficients_info(m.name);
    EXPECT_EQ(info.image, m.image);
    EXPECT_EQ(info.basis, "pca");
    EXPECT_EQ(info.method, "pca");
    EXPECT_EQ(info.k, 3u);
    std::vector<float> c(info.height * info.width * 3);
    std::vector<std::uint8_t> mask(info.height * info.width);
    out.read_coefficient_rows(m.name, 0, info.height, c, mask);
    double err2 = 0, sum2 = 0;
    std::uint64_t valid = 0;
    for (std::size_t p = 0; p < cube->height * cube->width; ++p) {
      ASSERT_EQ(mask[p] != 0, cube->mask[p] != 0) << p;
      if (!cube->mask[p]) {
        for (std::size_t j = 0; j < 3; ++j) EXPECT_EQ(c[p * 3 + j], 0.0f);
        continue;
      }
      ++valid;
      Eigen::VectorXd x(kB);
      for (std::size_t k = 0; k < kB; ++k) x[Eigen::Index(k)] = cube->data[p * kB + k];
      const Eigen::VectorXd coef = v * (x - basis.mean);
      for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(c[p * 3 + j], coef[Eigen::Index(j)], 1e-6) << p;
      err2 += (x - basis.mean - v.transpose() * coef).squaredNorm();
      sum2 += x.squaredNorm();
    }
    EXPECT_EQ(m.valid, valid);
    EXPECT_EQ(m.error.count, valid);
    EXPECT_NEAR(m.sum_sq, sum2, 1e-9 * sum2);
    EXPECT_NEAR(m.relative_error(), std::sqrt(err2 / sum2), 1e-9);
  }
}

TEST(CoefficientMaps, DoNotDependOnTheThreadCountOrTheBlockSize) {
  Fixture f;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = f.write(f.dir / "one.h5");
  omp_set_num_threads(2);
  const auto two = f.write(f.dir / "two.h5");
  const auto big = f.write(f.dir / "big.h5", 1 << 20);
  omp_set_num_threads(saved);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(one[i].error.sum_sq, two[i].error.sum_sq);
    EXPECT_EQ(one[i].sum_sq, two[i].sum_sq);
    EXPECT_NEAR(one[i].error.sum_sq, big[i].error.sum_sq, 1e-12 * one[i].sum_sq);
    std::vector<std::vector<float>> data;
    for (const char* file : {"one.h5", "two.h5", "big.h5"}) {
      const store::Store s = store::Store::open(f.dir / file);
      const auto info = s.coefficients_info(one[i].name);
      std::vector<float> c(info.height * info.width * info.k);
      std::vector<std::uint8_t> m(info.height * info.width);
      s.read_coefficient_rows(one[i].name, 0, info.height, c, m);
      data.push_back(c);
    }
    EXPECT_EQ(data[0], data[1]);
    EXPECT_EQ(data[0], data[2]);
  }
}

TEST(CoefficientMaps, NeedOneNamePerImageAndTheBasisGrid) {
  Fixture f;
  const store::Store s = store::Store::open(f.db);
  const Projector projector(s.read_basis("pca"), 3, "pca");
  const store::BlockReader reader(s, {.image_globs = {"*"}});
  const std::vector<std::string> one = {"a.pca"};
  store::StoreWriter w(f.dir / "out.h5", {});
  EXPECT_THROW(write_coefficient_maps(s, reader, projector, one, {}, w), UsageError);
  store::Basis other = pca_basis();
  other.wavelengths = WavelengthGrid::range(410, 410 + 20 * double(kB - 1), 20);
  const Projector shifted(other, 3, "other");
  const std::vector<std::string> two = {"a.o", "b.o"};
  EXPECT_THROW(write_coefficient_maps(s, reader, shifted, two, {}, w), InputError);
}

}  // namespace
}  // namespace specula::stats
