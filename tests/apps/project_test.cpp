// `specula project`: an image whose valid spectra lie in a 3-D affine subspace is reconstructed exactly from
// three principal components of a basis learned on it, and every extra component only lowers the error.
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <vector>

#include "specula/stats/moments.h"
#include "specula/stats/pca.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

constexpr std::size_t kH = 12, kW = 20, kB = 31;

// The image: mean + sum of three orthonormal spectra with per-pixel weights; masked pixels (zeros once
// stored) lie off the subspace and must not count in the error statistics.
store::Cube subspace_cube() {
  Eigen::MatrixXd random(kB, 3);
  for (Eigen::Index b = 0; b < Eigen::Index(kB); ++b)
    for (Eigen::Index j = 0; j < 3; ++j) random(b, j) = std::sin(0.37 * double(b + 1) * double(j + 1) + double(j));
  const Eigen::MatrixXd q =
      Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ() * Eigen::MatrixXd::Identity(kB, 3);
  store::Cube c;
  c.resize(kH, kW, kB);
  c.wavelengths = WavelengthGrid::range(400, 700, 10);
  c.units = "reflectance";
  c.mask.assign(kH * kW, 1);
  for (std::size_t y = 0; y < kH; ++y)
    for (std::size_t x = 0; x < kW; ++x) {
      const double a = 0.3 * std::sin(0.5 * double(x)), b = 0.2 * std::cos(0.7 * double(y)),
                   d = 0.1 * std::sin(double(x * y));
      for (std::size_t band = 0; band < kB; ++band) {
        const Eigen::Index i = Eigen::Index(band);
        c.pixel(y, x)[band] = float(0.5 + 0.1 * std::sin(0.1 * double(band)) + a * q(i, 0) + b * q(i, 1) + d * q(i, 2));
      }
    }
  for (std::size_t x = 0; x < 3; ++x) {
    c.mask[x] = 0;
    for (std::size_t band = 0; band < kB; ++band) c.pixel(0, x)[band] = float(band % 2 ? 0.9 : 0.05);
  }
  return c;
}

// Learns a PCA basis on the valid pixels the way specula pca does: streamed moments, then pca_basis.
store::Basis learn(const store::Cube& c) {
  std::vector<double> rows;
  for (std::size_t p = 0; p < kH * kW; ++p)
    if (c.mask[p])
      rows.insert(rows.end(), c.data.begin() + std::ptrdiff_t(p * kB), c.data.begin() + std::ptrdiff_t((p + 1) * kB));
  stats::Moments m(kB);
  m.add(Eigen::Map<const RowMatrixXd>(rows.data(), Eigen::Index(rows.size() / kB), Eigen::Index(kB)));
  return stats::pca_basis(m, c.wavelengths);
}

struct Fixture {
  test::ScratchDir dir;
  std::filesystem::path db = dir / "db.h5";
  store::Cube cube = subspace_cube();
  Fixture() {
    store::StoreWriter w(db, {});
    w.add_image("scene", cube);
    w.add_basis("b", learn(cube));
    store::Cube narrow;
    narrow.resize(2, 2, 29);
    narrow.wavelengths = WavelengthGrid::range(420, 700, 10);
    narrow.units = "reflectance";
    std::fill(narrow.data.begin(), narrow.data.end(), 0.5f);
    w.add_image("narrow", narrow);
    store::Basis nmf;
    nmf.method = "nmf";
    nmf.wavelengths = cube.wavelengths;
    nmf.components = Eigen::MatrixXd::Constant(2, Eigen::Index(kB), 0.1);
    nmf.n = 10;
    w.add_basis("nmf", nmf);
    w.commit();
  }
  std::string base() const { return "project '" + db.string() + "' --basis b --image scene "; }
};

// The "key":value numbers of a --json answer, in order.
std::vector<double> numbers(const std::string& json, const std::string& key) {
  std::vector<double> v;
  const std::string pattern = "\"" + key + "\":";
  for (auto at = json.find(pattern); at != std::string::npos; at = json.find(pattern, at + 1))
    v.push_back(std::stod(json.substr(at + pattern.size())));
  return v;
}

std::size_t lines(const std::string& s) { return std::size_t(std::count(s.begin(), s.end(), '\n')); }

}  // namespace

TEST(ProjectCli, ThreeComponentsReconstructASubspaceImageAndErrorFallsWithK) {
  Fixture f;
  const auto out = f.dir / "out";
  auto r = run_specula(f.base() + "-k 1,2,3,4,31 --json -o '" + out.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto k = numbers(r.output, "k"), rms = numbers(r.output, "rms"), mx = numbers(r.output, "max_error");
  ASSERT_EQ(k, (std::vector<double>{1, 2, 3, 4, 31})) << r.output;
  ASSERT_EQ(rms.size(), 5u);
  EXPECT_GT(rms[0], 1e-3) << r.output;
  EXPECT_GT(rms[1], 1e-4) << r.output;
  EXPECT_LT(rms[2], 1e-6) << r.output;
  EXPECT_LT(rms[4], 1e-7) << r.output;
  EXPECT_LT(mx[2], 1e-5) << r.output;
  for (std::size_t i = 0; i + 1 < rms.size(); ++i) EXPECT_LE(rms[i + 1], rms[i] + 1e-9) << r.output;
  EXPECT_NE(r.output.find("rms_definition"), std::string::npos);

  for (const char* name : {"reconstruction-k3.exr", "preview-k3.png", "error-k3.png", "preview-k31.png", "panel.png"})
    EXPECT_TRUE(std::filesystem::exists(out / name)) << name;
  const auto panel = store::read_png(out / "panel.png");
  EXPECT_EQ(panel.channels, 3u);
  // Six columns (the original and five reconstructions) at least as wide as the image; two rows of images.
  EXPECT_GE(panel.width, 6 * kW);
  EXPECT_LE(panel.width, 6 * 80u);
  EXPECT_GE(panel.height, 2 * kH + 30);
  EXPECT_LE(panel.height, 2 * kH + 80);
  const auto error_png = store::read_png(out / "error-k1.png");
  EXPECT_GE(error_png.width, kW);
  EXPECT_GT(error_png.height, kH);

  const store::Cube back = store::read_spectral_exr(out / "reconstruction-k3.exr");
  ASSERT_EQ(back.height, kH);
  ASSERT_EQ(back.width, kW);
  ASSERT_EQ(back.bands, kB);
  EXPECT_TRUE(back.wavelengths.approx_equal(f.cube.wavelengths));
  EXPECT_EQ(back.units, "reflectance");
  EXPECT_EQ(back.mask, f.cube.mask);
  double worst = 0;
  for (std::size_t p = 0; p < kH * kW; ++p)
    if (f.cube.mask[p])
      for (std::size_t b = 0; b < kB; ++b)
        worst = std::max(worst, double(std::abs(back.data[p * kB + b] - f.cube.data[p * kB + b])));
  EXPECT_LT(worst, 1e-5);
}

TEST(ProjectCli, SingleKWritesAnExrAndTextAndCanAddToTheStore) {
  Fixture f;
  auto r = run_specula(f.base() + "-k 3 --into-store rec -o '" + (f.dir / "r.exr").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("k=3: rms "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("(L2 over bands)"), std::string::npos) << r.output;
  EXPECT_TRUE(std::filesystem::exists(f.dir / "r.exr"));
  EXPECT_TRUE(std::filesystem::exists(f.dir / "r-preview.png"));
  EXPECT_TRUE(std::filesystem::exists(f.dir / "r-error.png"));
  EXPECT_FALSE(std::filesystem::exists(f.dir / "panel.png"));
  const auto s = store::Store::open(f.db);
  const store::Cube stored = s.read_image("rec-k3");
  EXPECT_EQ(stored.data, store::read_spectral_exr(f.dir / "r.exr").data);
  EXPECT_EQ(s.image_info("rec-k3").provenance.importer, "pca-project");

  r = run_specula(f.base() + "-k 3 --into-store rec -o '" + (f.dir / "again").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("already exists"), std::string::npos) << r.output;
}

TEST(ProjectCli, BadInputsAreOneLineErrors) {
  Fixture f;
  const std::string out = " -o '" + (f.dir / "out").string() + "'";
  auto r = run_specula("project '" + f.db.string() + "' --basis nope --image scene -k 3" + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("no basis 'nope'"), std::string::npos) << r.output;

  for (const char* k : {"0", "32"}) {
    r = run_specula(f.base() + "-k " + k + out);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(lines(r.output), 1u) << r.output;
    EXPECT_NE(r.output.find("give k between 1 and 31"), std::string::npos) << r.output;
  }

  r = run_specula("project '" + f.db.string() + "' --basis b --image narrow -k 3" + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("29 bands"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("31 bands"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--wavelengths"), std::string::npos) << r.output;

  r = run_specula("project '" + f.db.string() + "' --basis nmf --image scene -k 1" + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("NMF basis nmf has 2 components and projects onto all of them"), std::string::npos)
      << r.output;

  r = run_specula(f.base() + "-k 1,3 -o '" + (f.dir / "one.exr").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("give a directory"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(f.dir / "out"));
}
