// `specula import` of neural BRDF weights (codec/nbrdf.h): a directory of real NBRDF files in one command lands as
// spectral grids whose RGB is the network's; a bad file among them gives one line and leaves the store as it was.
#include <gtest/gtest.h>

#include <filesystem>

#include "specula/codec/nbrdf.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/illuminant.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

TEST(ImportNbrdf, ADirectoryLandsAsSpectralGridsWhoseColourIsTheNetworks) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  const auto src = test::shared_dir() / "data" / "brdf" / "nbrdf-merl";
  std::filesystem::create_directories(dir / "in");
  for (const char* m : {"red-plastic", "white-marble"})
    std::filesystem::copy_file(src / (std::string(m) + ".h5"), dir / "in" / (std::string(m) + ".h5"));
  const auto store = (dir / "db.h5").string();

  test::RunResult r = run_specula("import '" + (dir / "in").string() + "' -o '" + store + "'");
  EXPECT_NE(r.status, 0) << r.output;  // a store holds spectral grids: --uplift is asked for
  EXPECT_NE(r.output.find("--uplift"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(store));

  r = run_specula("import '" + (dir / "in").string() + "' --uplift -o '" + store + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Store s = store::Store::open(store);
  ASSERT_EQ(s.grids(), (std::vector<std::string>{"red-plastic", "white-marble"}));
  const store::Grid g = s.read_grid("red-plastic");
  EXPECT_EQ(g.bands(), 31u);
  EXPECT_EQ(g.provenance.importer, "nbrdf");
  // The grid seen in RGB under D65 is the network's RGB wherever that is inside the gamut of spectra.
  const codec::MerlBrdf net = codec::nbrdf_to_merl(store::read_nbrdf(src / "red-plastic.h5"));
  const auto w = codec::rgb_weights(g.wavelengths, parse_illuminant("D65", g.wavelengths));
  const codec::MerlBrdf back = codec::grid_to_merl(g, w).brdf;
  double worst = 0;
  std::size_t compared = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 97) {
    ASSERT_EQ(back.has_data(cell), net.has_data(cell)) << cell;
    if (!net.has_data(cell)) continue;
    const Eigen::Vector3d a(net.value(0, cell), net.value(1, cell), net.value(2, cell));
    const Eigen::Vector3d b(back.value(0, cell), back.value(1, cell), back.value(2, cell));
    worst = std::max(worst, (a - b).norm() / std::max(a.norm(), 1e-3));
    ++compared;
  }
  EXPECT_GT(compared, 5000u);
  EXPECT_LT(worst, 0.02);  // red plastic's red is saturated: the non-negative uplift reproduces it to 2 %
}

TEST(ImportNbrdf, ABadFileAmongGoodOnesIsOneLineAndTheStoreStaysAsItWas) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  const auto src = test::shared_dir() / "data" / "brdf" / "nbrdf-merl";
  const auto store = (dir / "db.h5").string();
  ASSERT_EQ(
      run_specula("import '" + (src / "pink-fabric.h5").string() + "' --uplift --name felt -o '" + store + "'").status,
      0);
  const std::string before = test::read_bytes(store);
  std::filesystem::create_directories(dir / "in");
  std::filesystem::copy_file(src / "brass.h5", dir / "in" / "brass.h5");
  test::write_file(dir / "in" / "zz-broken.h5", "HDF5 it is not\n");
  const test::RunResult r =
      run_specula("import '" + (dir / "in").string() + "' --format nbrdf --uplift -o '" + store + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("zz-broken.h5: not an HDF5 file"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_EQ(test::read_bytes(store), before);
  EXPECT_EQ(store::Store::open(store).grids(), std::vector<std::string>{"felt"});
}
