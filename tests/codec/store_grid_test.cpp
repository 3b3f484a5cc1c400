#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/store/h5.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

namespace {

Grid make_grid(std::size_t bands, unsigned seed) {
  Grid g;
  g.wavelengths = WavelengthGrid::range(450, 450 + 100.0 * double(bands - 1), 100);
  g.scale = 0.25;
  g.brdf.resize(bands * brdf::kMerlCells);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.1f, 3.0f);
  for (float& v : g.brdf) v = u(rng);
  g.provenance.source_file = "ward.spgrid";
  g.provenance.importer = "test";
  return g;
}

}  // namespace

TEST(StoreGrid, RoundTripKeepsValuesAndMetadata) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  const Grid g = make_grid(2, 3);
  {
    StoreWriter w(path, {.compression = Compression::parse("deflate:1"), .command_line = "specula test"});
    w.add_grid("ward", g);
    w.commit();
  }
  const Store s = Store::open(path);
  ASSERT_EQ(s.grids(), std::vector<std::string>{"ward"});
  const GridInfo info = s.grid_info("ward");
  EXPECT_EQ(info.bands, 2u);
  EXPECT_EQ(info.scale, 0.25);
  EXPECT_EQ(info.units, "1/sr");
  EXPECT_EQ(info.compression, "shuffle+deflate:1");
  EXPECT_EQ(info.provenance.source_file, "ward.spgrid");
  EXPECT_TRUE(info.wavelengths.approx_equal(g.wavelengths, 0));
  const Grid r = s.read_grid("ward");
  EXPECT_EQ(r.brdf, g.brdf);
  EXPECT_EQ(r.scale, 0.25);
  // The documented layout, read with plain HDF5: (bands, 90, 90, 180) float32, chunked.
  h5::Id root(H5Fopen(s.path().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  h5::Id ds(H5Dopen2(root, "/grids/ward/brdf", H5P_DEFAULT));
  ASSERT_TRUE(ds.valid());
  EXPECT_EQ(h5::shape(ds, "t"), (std::vector<hsize_t>{2, 90, 90, 180}));
  h5::Id type(H5Dget_type(ds));
  EXPECT_EQ(H5Tget_class(type), H5T_FLOAT);
  EXPECT_EQ(H5Tget_size(type), 4u);
  h5::Id dcpl(H5Dget_create_plist(ds));
  EXPECT_EQ(H5Pget_layout(dcpl), H5D_CHUNKED);
  // Band 1, theta_h 3, theta_d 4, phi_d 5 is element (1, 3, 4, 5).
  const hsize_t start[4] = {1, 3, 4, 5}, count[4] = {1, 1, 1, 1};
  h5::Id fspace(H5Dget_space(ds));
  H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr);
  h5::Id mspace(H5Screate_simple(1, count, nullptr));
  float v = 0;
  H5Dread(ds, H5T_NATIVE_FLOAT, mspace, fspace, H5P_DEFAULT, &v);
  EXPECT_EQ(v, g.brdf[brdf::kMerlCells + brdf::merl_index({3, 4, 5})]);
}

TEST(StoreGrid, BadGridsLeaveTheStoreUntouched) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_grid("a", make_grid(1, 4));
    w.commit();
  }
  const std::string before = test::read_bytes(path);
  Grid nan = make_grid(1, 5);
  nan.brdf[12345] = std::nanf("");
  {
    StoreWriter w(path, {});
    const std::string msg = test::input_error_text([&] { w.add_grid("b", nan); });
    EXPECT_NE(msg.find("cell 12345"), std::string::npos) << msg;
    Grid short_grid = make_grid(1, 6);
    short_grid.brdf.pop_back();
    EXPECT_THROW(w.add_grid("c", short_grid), UsageError);
    Grid zero_scale = make_grid(1, 7);
    zero_scale.scale = 0;
    EXPECT_THROW(w.add_grid("d", zero_scale), InputError);
    EXPECT_THROW(w.add_grid("a", make_grid(1, 8)), InputError);  // exists, no --replace
  }
  EXPECT_EQ(test::read_bytes(path), before);
  const std::string msg = test::input_error_text([&] { Store::open(path).grid_info("zz"); });
  EXPECT_NE(msg.find("no grid 'zz' (grids: a)"), std::string::npos) << msg;
}
