// `specula coefficients`: an image made of a planted non-negative factorisation C·S gives back C on the NMF basis S;
// on a PCA basis the map equals (x - mean) V_k^T computed here; the map and its error do not depend on the thread
// count; bad requests are one-line errors that leave the store as it was.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <vector>

#include "specula/core/nnls.h"
#include "specula/stats/moments.h"
#include "specula/stats/pca.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

constexpr std::size_t kB = 31, kK = 3;

// Three smooth non-negative spectra of unit norm: the planted NMF basis.
Eigen::MatrixXd planted_basis() {
  Eigen::MatrixXd s(kK, kB);
  for (std::size_t j = 0; j < kK; ++j)
    for (std::size_t b = 0; b < kB; ++b) {
      const double t = double(b) / double(kB - 1), centre = 0.15 + 0.35 * double(j);
      s(Eigen::Index(j), Eigen::Index(b)) = std::exp(-0.5 * std::pow((t - centre) / 0.18, 2)) + 0.02;
    }
  s.rowwise().normalize();
  return s;
}

// Image = C·S with non-negative C (a quarter of the entries exactly zero); every 11th pixel masked.
struct Planted {
  store::Cube cube;
  std::vector<double> coefficients;  // pixels x k
};
Planted planted_image(std::size_t h, std::size_t w, unsigned seed, const Eigen::MatrixXd& s) {
  Planted p;
  p.cube.resize(h, w, kB);
  p.cube.wavelengths = WavelengthGrid::range(420, 720, 10);
  p.cube.units = "reflectance";
  p.cube.mask.assign(h * w, 1);
  p.coefficients.resize(h * w * kK);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t px = 0; px < h * w; ++px) {
    Eigen::RowVectorXd x = Eigen::RowVectorXd::Zero(Eigen::Index(kB));
    for (std::size_t j = 0; j < kK; ++j) {
      const double c = u(rng) < 0.25 ? 0.0 : 0.05 + u(rng);
      p.coefficients[px * kK + j] = c;
      x += c * s.row(Eigen::Index(j));
    }
    for (std::size_t b = 0; b < kB; ++b) p.cube.data[px * kB + b] = float(x(Eigen::Index(b)));
    if (px % 11 == 5) p.cube.mask[px] = 0;
  }
  return p;
}

store::Basis learn_pca(const store::Cube& c) {
  stats::Moments m(kB);
  RowMatrixXd rows(1, Eigen::Index(kB));
  for (std::size_t p = 0; p < c.height * c.width; ++p)
    if (c.mask[p]) {
      for (std::size_t b = 0; b < kB; ++b) rows(0, Eigen::Index(b)) = c.data[p * kB + b];
      m.add(rows);
    }
  return stats::pca_basis(m, c.wavelengths);
}

struct Fixture {
  test::ScratchDir dir;
  std::filesystem::path db = dir / "db.h5";
  Eigen::MatrixXd s = planted_basis();
  Planted a = planted_image(14, 23, 1, s), b = planted_image(9, 17, 2, s);
  Fixture() {
    store::StoreWriter w(db, {});
    w.add_image("scene-a", a.cube);
    w.add_image("scene-b", b.cube);
    store::Cube narrow;
    narrow.resize(2, 2, 29);
    narrow.wavelengths = WavelengthGrid::range(420, 700, 10);
    std::fill(narrow.data.begin(), narrow.data.end(), 0.5f);
    w.add_image("narrow", narrow);
    store::Basis nmf;
    nmf.method = "nmf";
    nmf.wavelengths = a.cube.wavelengths;
    nmf.components = s;
    nmf.n = 1;
    w.add_basis("nmf", nmf);
    w.add_basis("pca", learn_pca(a.cube));
    w.commit();
  }
  std::string base() const { return "coefficients '" + db.string() + "' "; }
};

std::vector<float> whole_map(const store::Store& s, const std::string& name,
                             std::vector<std::uint8_t>* mask = nullptr) {
  const auto info = s.coefficients_info(name);
  std::vector<float> c(info.height * info.width * info.k);
  std::vector<std::uint8_t> m(info.height * info.width);
  s.read_coefficient_rows(name, 0, info.height, c, m);
  if (mask) *mask = m;
  return c;
}

std::size_t lines(const std::string& s) { return std::size_t(std::count(s.begin(), s.end(), '\n')); }

}  // namespace

TEST(CoefficientsCli, NmfMapsRecoverAPlantedFactorisationForEveryMatchingImage) {
  Fixture f;
  const auto plots = f.dir / "plots";
  auto r = run_specula(f.base() + "--basis nmf --images 'scene-*' --json --plots '" + plots.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "k"), 3.0) << r.output;
  EXPECT_LT(test::json_number(r.output, "rel_error"), 1e-6) << r.output;
  const auto ls = run_specula("ls '" + f.db.string() + "'");
  EXPECT_NE(ls.output.find("coefficients scene-a.nmf"), std::string::npos) << ls.output;
  const auto info = run_specula("info '" + f.db.string() + "' scene-b.nmf --json");
  EXPECT_NE(
      info.output.find(
          R"("kind":"coefficients","name":"scene-b.nmf","image":"scene-b","basis":"nmf","method":"nmf","height":9,"width":17,"k":3)"),
      std::string::npos)
      << info.output;
  const store::Store s = store::Store::open(f.db);
  EXPECT_EQ(s.coefficients(), (std::vector<std::string>{"scene-a.nmf", "scene-b.nmf"}));
  for (const auto& [name, planted] : {std::pair{"scene-a.nmf", &f.a}, std::pair{"scene-b.nmf", &f.b}}) {
    const auto info = s.coefficients_info(name);
    EXPECT_EQ(info.method, "nmf");
    EXPECT_EQ(info.basis, "nmf");
    EXPECT_EQ(info.height, planted->cube.height);
    EXPECT_EQ(info.width, planted->cube.width);
    std::vector<std::uint8_t> mask;
    const std::vector<float> c = whole_map(s, name, &mask);
    EXPECT_EQ(mask, planted->cube.mask);
    double worst = 0;
    for (std::size_t p = 0; p < mask.size(); ++p)
      for (std::size_t j = 0; j < kK; ++j) {
        const double want = mask[p] ? planted->coefficients[p * kK + j] : 0.0;
        worst = std::max(worst, std::abs(double(c[p * kK + j]) - want));
        if (want == 0.0) {
          EXPECT_GE(c[p * kK + j], 0.0f);
        }
      }
    EXPECT_LT(worst, 1e-6) << name;
    EXPECT_EQ(s.coefficients_basis(name).components, f.s);
    const auto png = store::read_png(plots / (std::string(name) + ".png"));
    EXPECT_GE(png.width, 3 * planted->cube.width);
    EXPECT_GT(png.height, planted->cube.height);
  }
}

TEST(CoefficientsCli, PcaMapsAreTheProjectionOnTheFirstKComponentsAndReconstructTheImage) {
  Fixture f;
  auto r = run_specula(f.base() + "--basis pca -k 2 --images scene-b --name b2");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("/coefficients/b2"), std::string::npos) << r.output;
  r = run_specula(f.base() + "--basis pca -k 3 --images scene-a --name a3 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  // The planted image spans three spectra, so three principal components (around the mean) hold it all but
  // rounding; two do not.
  EXPECT_LT(test::json_number(r.output, "rel_error"), 1e-6) << r.output;

  const store::Store s = store::Store::open(f.db);
  const store::Basis pca = s.read_basis("pca");
  for (const auto& [name, planted, k] : {std::tuple{"b2", &f.b, 2}, std::tuple{"a3", &f.a, 3}}) {
    const std::vector<float> c = whole_map(s, name);
    const store::Basis kept = s.coefficients_basis(name);
    EXPECT_EQ(kept.components, pca.components.topRows(k));
    EXPECT_EQ(kept.mean, pca.mean);
    const store::Cube& img = planted->cube;
    double worst = 0, worst_recon = 0;
    for (std::size_t p = 0; p < img.height * img.width; ++p) {
      if (!img.mask[p]) continue;
      Eigen::RowVectorXd x(kB);
      for (std::size_t b = 0; b < kB; ++b) x(Eigen::Index(b)) = img.data[p * kB + b];
      const Eigen::RowVectorXd want = (x - pca.mean.transpose()) * pca.components.topRows(k).transpose();
      Eigen::RowVectorXd got(k);
      for (int j = 0; j < k; ++j) got(j) = c[p * std::size_t(k) + std::size_t(j)];
      worst = std::max(worst, (got - want).cwiseAbs().maxCoeff());
      worst_recon = std::max(worst_recon, (kept.mean.transpose() + got * kept.components - x).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(worst, 1e-5) << name;
    if (k == 3) {
      EXPECT_LT(worst_recon, 1e-5) << name;
    } else {
      EXPECT_GT(worst_recon, 1e-3) << name;
    }
  }
}

TEST(CoefficientsCli, InexactNnlsMapsMatchBruteForceAndDoNotDependOnTheThreadCount) {
  test::ScratchDir dir;
  const Eigen::MatrixXd s = planted_basis();
  // Large enough for several blocks of the reader; two of the three planted spectra, so constraints are active.
  const Planted big = planted_image(300, 256, 7, s);
  const auto one = dir / "one.h5", two = dir / "copy" / "one.h5";
  store::Basis nmf;
  nmf.method = "nmf";
  nmf.wavelengths = big.cube.wavelengths;
  nmf.components = s.bottomRows(2);
  nmf.n = 1;
  {
    store::StoreWriter w(one, {});
    w.add_image("big", big.cube);
    w.add_basis("nmf2", nmf);
    w.commit();
  }
  std::filesystem::create_directories(dir / "copy");  // a store is copied as its root and data directory together
  std::filesystem::copy_file(one, two);
  std::filesystem::copy(dir / "one.h5.d", dir / "copy" / "one.h5.d", std::filesystem::copy_options::recursive);
  const auto r1 =
      test::run_shell("OMP_NUM_THREADS=1 '" SPECULA_BINARY "' coefficients '" + one.string() + "' --basis nmf2 --json");
  const auto r2 =
      test::run_shell("OMP_NUM_THREADS=2 '" SPECULA_BINARY "' coefficients '" + two.string() + "' --basis nmf2 --json");
  ASSERT_EQ(r1.status, 0) << r1.output;
  ASSERT_EQ(r2.status, 0) << r2.output;
  const double rel = test::json_number(r1.output, "rel_error");
  EXPECT_EQ(rel, test::json_number(r2.output, "rel_error"));
  EXPECT_GT(rel, 0.05) << "the basis was meant to miss part of the data";
  const std::vector<float> c1 = whole_map(store::Store::open(one), "big.nmf2");
  EXPECT_EQ(c1, whole_map(store::Store::open(two), "big.nmf2"));

  // Every 97th valid pixel against brute-force enumeration of active sets.
  const Eigen::MatrixXd gram = nmf.components * nmf.components.transpose();
  double worst = 0;
  std::size_t checked = 0, clamped = 0;
  for (std::size_t p = 0; p < big.cube.height * big.cube.width; p += 97) {
    if (!big.cube.mask[p]) continue;
    Eigen::VectorXd x(kB);
    for (std::size_t b = 0; b < kB; ++b) x(Eigen::Index(b)) = big.cube.data[p * kB + b];
    const Eigen::VectorXd want = nnls_brute_force(gram, nmf.components * x);
    for (Eigen::Index j = 0; j < 2; ++j) {
      worst = std::max(worst, std::abs(double(c1[p * 2 + std::size_t(j)]) - want(j)) / std::max(1.0, want(j)));
      clamped += want(j) == 0.0;
    }
    ++checked;
  }
  EXPECT_GT(checked, 500u);
  EXPECT_GT(clamped, 10u) << "no active constraint was exercised";
  EXPECT_LT(worst, 1e-6);
}

TEST(CoefficientsCli, BadRequestsAreOneLineErrorsAndLeaveTheStoreAsItWas) {
  Fixture f;
  ASSERT_EQ(run_specula(f.base() + "--basis nmf --images scene-a").status, 0);
  const std::string before = test::read_bytes(f.db);
  struct Case {
    std::string args, expect;
  };
  const std::vector<Case> cases = {
      {"--basis nmf --images scene-a", "coefficient map scene-a.nmf exists already"},
      {"--basis nmf -k 2 --images scene-b", "NMF basis nmf has 3 components and projects onto all of them"},
      {"--basis pca -k 32 --images scene-b", "give k between 1 and 31"},
      {"--basis nope --images scene-b", "no basis 'nope'"},
      {"--basis nmf --images 'scene-*' --name x", "--name x names one map, but 2 images match"},
      {"--basis nmf --images narrow", "29 bands"},
      {"--basis nmf --images nothing", "nothing"},
      {"--basis nmf --images scene-b --name 'bad/name'", "bad/name"},
  };
  for (const Case& c : cases) {
    const auto r = run_specula(f.base() + c.args);
    EXPECT_EQ(r.status, 1) << c.args << "\n" << r.output;
    EXPECT_EQ(lines(r.output), 1u) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
  }
  // A disk that fills up after the first rows: the store is left as it was, and no temporary file stays.
  const auto full = test::run_shell("SPECULA_INJECT_WRITE_FAILURE=1 '" SPECULA_BINARY "' " + f.base() +
                                    "--basis nmf --images scene-b");
  EXPECT_EQ(full.status, 1) << full.output;
  EXPECT_NE(full.output.find("No space left on device"), std::string::npos) << full.output;
  EXPECT_EQ(test::read_bytes(f.db), before);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(f.dir.path()), std::filesystem::directory_iterator()), 2)
      << "something beside the root and its data directory was left";
  EXPECT_TRUE(std::filesystem::is_empty(f.db.string() + ".d/tx")) << "the failed transaction's lock file was left";
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(f.db.string() + ".d/objects/coefficients"),
                          std::filesystem::directory_iterator()),
            1)
      << "the failed transaction's data file was left";
  const auto r = run_specula(f.base() + "--basis nmf --images scene-a --replace");
  EXPECT_EQ(r.status, 0) << r.output;
}

TEST(CoefficientsCli, H5pyReconstructsTheImageFromTheDocumentedLayout) {
  ASSERT_EQ(std::system("/usr/bin/python3 -c 'import h5py, numpy' >/dev/null 2>&1"), 0)
      << "Debian's python3-h5py is not installed: scripts/setup-deps (run by scripts/test) installs it";
  Fixture f;
  ASSERT_EQ(run_specula(f.base() + "--basis nmf --images scene-a").status, 0);
  ASSERT_EQ(run_specula(f.base() + "--basis pca -k 3 --images scene-a").status, 0);
  const std::string script =
      "import h5py, numpy as np, sys\n"
      "with h5py.File(sys.argv[1], 'r') as f:\n"
      "    img = f['images/scene-a']; cube = img['cube'][...]; mask = img['mask'][...].astype(bool)\n"
      "    for name in ('scene-a.nmf', 'scene-a.pca'):\n"
      "        m = f['coefficients/' + name]\n"
      "        assert m.attrs['kind'] == 'coefficients' and m.attrs['image'] == 'scene-a', dict(m.attrs)\n"
      "        assert m['coefficients'].attrs['axes'] == 'height,width,component'\n"
      "        recon = m['coefficients'][...] @ m['components'][...]\n"
      "        if m.attrs['method'] == 'pca': recon = recon + m['mean'][...]\n"
      "        assert (m['mask'][...].astype(bool) == mask).all()\n"
      "        assert int(m.attrs['valid_pixels']) == int(mask.sum())\n"
      "        err = np.abs(recon[mask] - cube[mask]).max()\n"
      "        assert err < 1e-5, (name, err)\n"
      "print('ok')\n";
  std::ofstream(f.dir / "check.py") << script;
  const auto r = test::run_shell("/usr/bin/python3 '" + (f.dir / "check.py").string() + "' '" + f.db.string() + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("ok"), std::string::npos) << r.output;
}
