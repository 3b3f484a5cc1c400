// A reader with only h5py and docs/store-format.md gets back exactly what was imported.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;

TEST(StoreFormat, H5pyReadsEveryObjectAndVerifiesTheIndexUsingOnlyTheDocumentedLayout) {
  if (std::system("/usr/bin/python3 -c 'import h5py, numpy' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "Debian's python3-h5py is not installed (scripts/setup-deps installs it)";
  test::ScratchDir dir;
  store::Cube c;
  c.resize(130, 77, 31);
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0.5f, 0.2f);
  for (auto& v : c.data) v = n(rng);
  c.mask.assign(130 * 77, 1);
  for (std::size_t i = 0; i < c.mask.size(); i += 5) c.mask[i] = 0;
  c.wavelengths = WavelengthGrid::range(420, 720, 10);
  {
    store::StoreWriter w(dir / "db.h5", {});
    w.add_image("scene", c);
    w.commit();
  }
  {  // a second transaction, so the root links objects of two data files
    store::StoreWriter w(dir / "db.h5", {});
    store::Collection col;
    col.names = {"a", "b", "c"};
    col.values.assign(3 * 31, 0.25f);
    col.wavelengths = c.wavelengths;
    w.add_collection("chips", col);
    store::Basis basis;
    basis.method = "pca";
    basis.wavelengths = c.wavelengths;
    basis.components = Eigen::MatrixXd::Identity(2, 31);
    basis.mean = Eigen::VectorXd::Zero(31);
    w.add_basis("pca", basis);
    w.commit();
  }
  std::ofstream(dir / "ref.f32", std::ios::binary)
      .write(reinterpret_cast<const char*>(c.data.data()), std::streamsize(c.data.size() * 4));
  std::ofstream(dir / "mask.u8", std::ios::binary)
      .write(reinterpret_cast<const char*>(c.mask.data()), std::streamsize(c.mask.size()));
  const std::string cmd = "/usr/bin/python3 '" SPECULA_SOURCE_DIR "/tests/store/read_with_h5py.py' '" +
                          (dir / "db.h5").string() + "' scene '" + (dir / "ref.f32").string() + "' '" +
                          (dir / "mask.u8").string() + "' 130 77 31 3 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0);
}
