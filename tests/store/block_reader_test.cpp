#include "specula/store/block_reader.h"
#include "specula/store/h5.h"

#include <gtest/gtest.h>

#include <random>

#include "specula/core/error.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

namespace {

Cube random_cube(std::size_t h, std::size_t w, std::size_t b, unsigned seed) {
  Cube c;
  c.resize(h, w, b);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 2.0f);
  for (auto& v : c.data) v = u(rng);
  c.mask.assign(h * w, 1);
  std::bernoulli_distribution drop(0.3);
  for (auto& m : c.mask) m = drop(rng) ? 0 : 1;
  c.wavelengths = WavelengthGrid::range(420, 420 + 10.0 * double(b - 1), 10);
  return c;
}

// Brute force: every valid spectrum of every cube, in image then row-major pixel order.
RowMatrixXd all_valid(const std::vector<Cube>& cubes) {
  std::vector<const float*> rows;
  for (const auto& c : cubes)
    for (std::size_t p = 0; p < c.height * c.width; ++p)
      if (c.mask[p]) rows.push_back(c.data.data() + p * c.bands);
  RowMatrixXd m(Eigen::Index(rows.size()), Eigen::Index(cubes[0].bands));
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (std::size_t b = 0; b < cubes[0].bands; ++b) m(Eigen::Index(i), Eigen::Index(b)) = rows[i][b];
  return m;
}

}  // namespace

class BlockReaderTest : public ::testing::TestWithParam<const char*> {};

TEST_P(BlockReaderTest, StreamsExactlyTheValidSpectraInOrder) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  // The third image is wider than one 1 MiB chunk row, so its chunks split the columns.
  std::vector<Cube> cubes{random_cube(300, 170, 31, 1), random_cube(97, 503, 31, 2), random_cube(3, 9000, 31, 5),
                          random_cube(1, 1, 31, 3)};
  {
    StoreWriter w(path, {.compression = Compression::parse(GetParam())});
    for (std::size_t i = 0; i < cubes.size(); ++i) w.add_image("img" + std::to_string(i), cubes[i]);
    w.commit();
  }
  Store s = Store::open(path);
  BlockReader reader(s, {}, 4096);
  EXPECT_TRUE(reader.direct());
  const RowMatrixXd expect = all_valid(cubes);
  ASSERT_EQ(reader.spectra(), std::uint64_t(expect.rows()));
  ASSERT_GT(reader.block_count(), 3u);
  std::vector<RowMatrixXd> blocks(reader.block_count());
  for_each_block<double>(reader, [&](std::size_t i, const RowMatrixXd& m, int) { blocks[i] = m; });
  Eigen::Index row = 0;
  for (const auto& b : blocks) {
    ASSERT_LE(std::size_t(b.rows()), reader.max_block_spectra());
    ASSERT_TRUE(b.isApprox(expect.middleRows(row, b.rows()), 0.0) || b.rows() == 0);
    row += b.rows();
  }
  EXPECT_EQ(row, expect.rows());
  // float blocks carry the same values
  RowMatrixXf f;
  reader.read(1, f);
  EXPECT_EQ(f.cast<double>(), blocks[1]);
}

INSTANTIATE_TEST_SUITE_P(Compression, BlockReaderTest, ::testing::Values("none", "deflate:1"));

TEST(BlockReader, SameBlocksForAnyThreadCount) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_image("a", random_cube(200, 100, 8, 4));
    w.commit();
  }
  Store s = Store::open(path);
  BlockReader reader(s, {}, 1000);
  auto sums = [&](int threads) {
    omp_set_num_threads(threads);
    std::vector<double> per_block(reader.block_count());
    for_each_block<double>(reader, [&](std::size_t i, const RowMatrixXd& m, int) { per_block[i] = m.sum(); });
    return per_block;
  };
  EXPECT_EQ(sums(1), sums(2));
}

TEST(BlockReader, SelectsByGlobOrCollectionAndRejectsMixedGrids) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  Collection col;
  col.names = {"x", "y", "z"};
  col.wavelengths = WavelengthGrid({500, 600});
  col.values = {1, 2, 3, 4, 5, 6};
  {
    StoreWriter w(path, {});
    w.add_image("day1", random_cube(10, 10, 31, 1));
    w.add_image("day2", random_cube(10, 10, 31, 2));
    w.add_image("night", random_cube(10, 10, 29, 3));
    w.add_collection("chips", col);
    w.commit();
  }
  Store s = Store::open(path);
  BlockReader days(s, {.image_globs = {"day*"}});
  EXPECT_EQ(days.source_names(), (std::vector<std::string>{"day1", "day2"}));
  try {
    BlockReader all(s, {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("29 bands"), std::string::npos) << e.what();
  }
  EXPECT_THROW(BlockReader(s, {.image_globs = {"none*"}}), InputError);
  BlockReader chips(s, {.collection = "chips"});
  EXPECT_EQ(chips.spectra(), 3u);
  RowMatrixXf m;
  chips.read(0, m);
  EXPECT_EQ(m(2, 1), 6.0f);
}

TEST(BlockReader, StreamsTheValuesOfScatteredSamples) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  const std::size_t n = 200000, b = 3;
  std::vector<double> angles(4 * n, 0.5);
  std::vector<float> values(n * b);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = float(i % 9973) * 0.25f;
  {
    StoreWriter w(path, {});
    w.create_samples("scan", WavelengthGrid({500, 600, 700}), "1/sr", {});
    w.append_samples("scan", angles, values);
    w.commit();
  }
  const Store s = Store::open(path);
  BlockReader reader(s, Selection{.samples = "scan"}, s.samples_info("scan").chunk_rows);
  EXPECT_TRUE(reader.direct());
  EXPECT_GT(reader.block_count(), 1u);
  EXPECT_EQ(reader.spectra(), n);
  std::vector<float> got;
  BlockReader::RawBlock raw;
  for (std::size_t i = 0; i < reader.block_count(); ++i) {
    reader.read_raw(i, raw);
    EXPECT_EQ(raw.valid, raw.pixels);
    got.insert(got.end(), raw.values.begin(), raw.values.end());
  }
  EXPECT_TRUE(got == values);
  EXPECT_NE(reader.describe_block(1).find("samples 'scan'"), std::string::npos) << reader.describe_block(1);
  EXPECT_THROW(BlockReader(s, Selection{.collection = "c", .samples = "scan"}), UsageError);
  EXPECT_THROW(BlockReader(s, Selection{.samples = "other"}), InputError);
}

TEST(BlockReader, BlocksOfSeveralStoresNameTheirImageEvenInAStoreNamedWithAColon) {
  test::ScratchDir dir;
  const auto pa = dir / "run:2.h5", pb = dir / "b.h5";
  for (const auto& [path, name] : {std::pair{pa, "left"}, std::pair{pb, "right"}}) {
    StoreWriter w(path, {});
    w.add_image(name, random_cube(20, 10, 4, 2));
    w.commit();
  }
  const std::vector<Store> stores = {Store::open(pa), Store::open(pb)};
  BlockReader reader(stores, {}, 100);
  ASSERT_GE(reader.block_count(), 2u);
  const std::string first = reader.describe_block(0), last = reader.describe_block(reader.block_count() - 1);
  EXPECT_NE(first.find("image 'left' rows 0-"), std::string::npos) << first;
  EXPECT_NE(last.find("image 'right' rows "), std::string::npos) << last;
}

TEST(BlockReader, ErrorsInsideTheStreamAreRethrown) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_image("a", random_cube(2000, 100, 4, 1));
    w.commit();
  }
  Store s = Store::open(path);
  BlockReader reader(s, {}, 100);
  ASSERT_GT(reader.block_count(), 3u);
  EXPECT_THROW(for_each_block<float>(reader,
                                     [](std::size_t i, const RowMatrixXf&, int) {
                                       if (i == 3) throw InputError("boom");
                                     }),
               InputError);
  request_interrupt();
  EXPECT_THROW(for_each_block<float>(reader, [](std::size_t, const RowMatrixXf&, int) {}), Interrupted);
  clear_interrupt();
}

TEST(BlockReader, FallsBackToHdf5ForFiltersItDoesNotDecode) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  Cube c = random_cube(40, 30, 5, 9);
  {
    StoreWriter w(path, {});
    w.add_image("plain", c);
    w.commit();
  }
  // Rewrite the cube with a Fletcher-32 checksum filter, which the direct path does not decode.
  {
    hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    H5Ldelete(f, "/images/plain/cube", H5P_DEFAULT);
    const hsize_t dims[3] = {40, 30, 5}, chunk[3] = {7, 30, 5};
    hid_t space = H5Screate_simple(3, dims, nullptr);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 3, chunk);
    H5Pset_fletcher32(dcpl);
    hid_t ds = H5Dcreate2(f, "/images/plain/cube", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    std::vector<float> zeroed = c.data;
    for (std::size_t p = 0; p < 40 * 30; ++p)
      if (!c.mask[p]) std::fill_n(zeroed.begin() + std::ptrdiff_t(p * 5), 5, 0.0f);
    H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, zeroed.data());
    H5Dclose(ds);
    H5Pclose(dcpl);
    H5Sclose(space);
    H5Fclose(f);
  }
  Store s = Store::open(path);
  BlockReader reader(s, {}, 100);
  EXPECT_FALSE(reader.direct());
  const RowMatrixXd expect = all_valid({c});
  Eigen::Index row = 0;
  RowMatrixXd m;
  for (std::size_t i = 0; i < reader.block_count(); ++i) {
    reader.read(i, m);
    ASSERT_EQ(m, expect.middleRows(row, m.rows()));
    row += m.rows();
  }
  EXPECT_EQ(row, expect.rows());
}
