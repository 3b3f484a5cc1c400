#include "specula/store/store.h"
#include "specula/store/h5.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

namespace {

Cube make_cube(std::size_t h, std::size_t w, std::size_t b, unsigned seed, bool with_mask) {
  Cube c;
  c.resize(h, w, b);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (auto& v : c.data) v = u(rng);
  if (with_mask) {
    c.mask.assign(h * w, 1);
    for (std::size_t i = 0; i < h * w; i += 7) c.mask[i] = 0;
  }
  c.wavelengths = WavelengthGrid::range(400, 400 + 10.0 * double(b - 1), 10);
  c.units = "radiance";
  c.provenance.source_file = "scene.raw";
  c.provenance.importer = "test";
  return c;
}

}  // namespace

TEST(Store, ImageRoundTripKeepsValuesMaskAndMetadata) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  Cube c = make_cube(37, 23, 5, 1, true);
  c.fwhm = {10, 10, 11, 12, 13};
  {
    StoreWriter w(path, {.compression = Compression::parse("deflate:6"), .command_line = "specula test"});
    w.add_image("scene", c);
    w.commit();
  }
  Store s = Store::open(path);
  ASSERT_EQ(s.images(), std::vector<std::string>{"scene"});
  ImageInfo info = s.image_info("scene");
  EXPECT_EQ(info.height, 37u);
  EXPECT_EQ(info.width, 23u);
  EXPECT_EQ(info.bands, 5u);
  EXPECT_EQ(info.units, "radiance");
  EXPECT_EQ(info.compression, "shuffle+deflate:6");
  EXPECT_EQ(info.provenance.source_file, "scene.raw");
  EXPECT_EQ(info.provenance.command_line, "specula test");
  std::uint64_t valid = 0;
  for (auto m : c.mask) valid += m;
  EXPECT_EQ(info.valid_pixels, valid);
  Cube r = s.read_image("scene");
  EXPECT_EQ(r.mask, c.mask);
  EXPECT_EQ(r.fwhm, c.fwhm);
  EXPECT_TRUE(r.wavelengths.approx_equal(c.wavelengths, 0));
  for (std::size_t p = 0; p < 37 * 23; ++p)
    for (std::size_t k = 0; k < 5; ++k) EXPECT_EQ(r.data[p * 5 + k], c.mask[p] ? c.data[p * 5 + k] : 0.0f);
}

TEST(Store, ReadPixelEqualsTheWholeImageAtEveryPixel) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  const Cube c = make_cube(19, 13, 7, 4, true);
  {
    StoreWriter w(path, {});
    w.add_image("scene", c);
    w.commit();
  }
  const Store s = Store::open(path);
  const Cube whole = s.read_image("scene");
  std::vector<float> v(7);
  for (std::size_t y = 0; y < 19; ++y)
    for (std::size_t x = 0; x < 13; ++x) {
      EXPECT_EQ(s.read_pixel("scene", x, y, v), c.mask[y * 13 + x] != 0) << x << "," << y;
      for (std::size_t b = 0; b < 7; ++b) EXPECT_EQ(v[b], whole.pixel(y, x)[b]) << x << "," << y << " " << b;
    }
  EXPECT_THROW(s.read_pixel("scene", 13, 0, v), UsageError);
  EXPECT_THROW(s.read_pixel("scene", 0, 19, v), UsageError);
  std::vector<float> short_buffer(6);
  EXPECT_THROW(s.read_pixel("scene", 0, 0, short_buffer), UsageError);
  EXPECT_THROW(s.read_pixel("nope", 0, 0, v), InputError);
}

TEST(Store, CollectionAndSamplesRoundTrip) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  Collection col;
  col.names = {"a", "b", "ünïcode"};
  col.wavelengths = WavelengthGrid({450, 550, 650});
  col.values = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  col.units = "reflectance";
  {
    StoreWriter w(path, {});
    w.add_collection("chips", col);
    w.create_samples("scan", WavelengthGrid({500, 600}), "1/sr", {});
    std::vector<double> a1{0.1, 0.2, 0.3, 0.4}, a2{1, 2, 3, 0.5, 1.1, 2.1, 3.1, 0.6};
    std::vector<float> v1{10, 11}, v2{20, 21, 30, 31};
    w.append_samples("scan", a1, v1);
    w.append_samples("scan", a2, v2);
    w.commit();
  }
  Store s = Store::open(path);
  Collection r = s.read_collection("chips");
  EXPECT_EQ(r.names, col.names);
  EXPECT_EQ(r.values, col.values);
  EXPECT_EQ(r.units, "reflectance");
  SamplesInfo si = s.samples_info("scan");
  ASSERT_EQ(si.size, 3u);
  std::vector<double> angles(12);
  std::vector<float> values(6);
  s.read_samples("scan", 0, 3, angles, values);
  EXPECT_EQ(values, (std::vector<float>{10, 11, 20, 21, 30, 31}));
  EXPECT_EQ(angles[4], 1);
  EXPECT_EQ(angles[11], 0.6);
  EXPECT_GT(si.chunk_rows, 0u);
  // Either dataset alone, from an offset.
  std::vector<double> a2(8, -1);
  std::vector<float> v2(4, -1);
  s.read_samples("scan", 1, 2, a2, {});
  EXPECT_EQ(a2[0], 1);
  s.read_samples("scan", 1, 2, {}, v2);
  EXPECT_EQ(v2, (std::vector<float>{20, 21, 30, 31}));
  EXPECT_THROW(s.read_samples("scan", 2, 2, {}, v2), UsageError);
}

// Grids are compressed chunk by chunk on every thread (the last theta_h chunk is partial) or written plain;
// both read back bit for bit, and HDF5 itself decodes the compressed chunks.
TEST(Store, GridsRoundTripCompressedOrNot) {
  test::ScratchDir dir;
  Grid g;
  g.wavelengths = WavelengthGrid({450, 550, 650});
  g.brdf.resize(3 * brdf::kMerlCells);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 3.0f);
  for (auto& v : g.brdf) v = u(rng);
  g.brdf[5] = -1;
  g.brdf.back() = 7.5f;
  for (const char* spec : {"deflate:6", "none"}) {
    const auto path = dir / (std::string(spec).substr(0, 4) + ".h5");
    {
      StoreWriter w(path, {.compression = Compression::parse(spec)});
      w.add_grid("g", g);
      w.commit();
    }
    const Grid r = Store::open(path).read_grid("g");
    EXPECT_TRUE(r.brdf == g.brdf) << spec;
    EXPECT_EQ(Store::open(path).grid_info("g").compression.find("deflate") != std::string::npos,
              std::string(spec) != "none")
        << spec;
  }
}

TEST(Store, SecondTransactionAddsToExistingStore) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_image("a", make_cube(8, 8, 3, 1, false));
    w.commit();
  }
  {
    StoreWriter w(path, {});
    w.add_image("b", make_cube(8, 8, 3, 2, false));
    EXPECT_THROW(w.add_image("a", make_cube(8, 8, 3, 3, false)), InputError);
    w.commit();
  }
  EXPECT_EQ(Store::open(path).images(), (std::vector<std::string>{"a", "b"}));
  {
    StoreWriter w(path, {.replace = true});
    w.add_image("a", make_cube(4, 4, 3, 3, false));
    w.commit();
  }
  EXPECT_EQ(Store::open(path).image_info("a").height, 4u);
}

TEST(Store, FailedOrAbandonedTransactionLeavesStoreByteIdentical) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_image("a", make_cube(64, 64, 31, 1, false));
    w.commit();
  }
  const std::string before = test::read_bytes(path);
  // A disk that fills up in the middle of the image.
  inject_write_failure_after(1);
  try {
    StoreWriter w(path, {.compression = Compression::parse("none")});
    w.add_image("b", make_cube(256, 256, 31, 2, false));
    w.commit();
    FAIL() << "the injected write failure did not surface";
  } catch (const LibraryError& e) {
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos);
  }
  inject_write_failure_after(-1);
  EXPECT_EQ(test::read_bytes(path), before);
  // NaN in a valid pixel.
  Cube bad = make_cube(4, 4, 3, 5, false);
  bad.data[17] = std::nanf("");
  {
    StoreWriter w(path, {});
    EXPECT_THROW(w.add_image("bad", bad), InputError);
  }
  EXPECT_EQ(test::read_bytes(path), before);
  std::size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir.path())) (void)e, ++files;
  EXPECT_EQ(files, 2u) << "a temporary file was left behind beside the root and its data directory";
  std::size_t data = 0;
  for (auto& e : std::filesystem::recursive_directory_iterator(dir / "s.h5.d" / "objects"))
    data += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(data, 1u) << "a failed transaction left a data file";
}

TEST(Store, RejectsFilesThatAreNotSpeculaStores) {
  test::ScratchDir dir;
  auto text = dir / "notes.h5";
  std::ofstream(text) << "just text";
  try {
    Store::open(text);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("notes.h5: not an HDF5 file"), std::string::npos) << e.what();
  }
  auto plain = dir / "plain.h5";
  hid_t f = H5Fcreate(plain.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(f);
  try {
    Store::open(plain);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a specula store"), std::string::npos) << e.what();
  }
  EXPECT_THROW(StoreWriter(plain, {}), InputError);
  EXPECT_THROW(Store::open(dir / "missing.h5"), InputError);
}

TEST(Store, RejectsNewerFormatVersionAndTruncatedFiles) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    w.add_image("a", make_cube(64, 64, 31, 1, false));
    w.commit();
  }
  {
    hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    h5::write_attr(f, "format_version", 99LL, "test");
    H5Fclose(f);
  }
  try {
    Store::open(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("version 99 is newer"), std::string::npos) << e.what();
  }
  // Truncate a valid store to half its size.
  auto path2 = dir / "t.h5";
  {
    StoreWriter w(path2, {.compression = Compression::parse("none")});
    w.add_image("a", make_cube(64, 64, 31, 1, false));
    w.commit();
  }
  std::filesystem::resize_file(path2, std::filesystem::file_size(path2) / 2);
  try {
    Store s = Store::open(path2);
    s.read_image("a");
    FAIL() << "truncated store was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("t.h5"), std::string::npos) << e.what();
  }
}

TEST(Store, NamesAndMissingObjectsAreExplained) {
  test::ScratchDir dir;
  auto path = dir / "s.h5";
  {
    StoreWriter w(path, {});
    EXPECT_THROW(w.add_image("../evil", make_cube(2, 2, 2, 1, false)), UsageError);
    EXPECT_THROW(w.add_image(".hidden", make_cube(2, 2, 2, 1, false)), UsageError);
    w.add_image("ok", make_cube(2, 2, 2, 1, false));
    w.commit();
  }
  try {
    Store::open(path).image_info("nope");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "s.h5: no image 'nope' (images: ok)");
  }
}

TEST(Compression, ParsesTheDocumentedForms) {
  EXPECT_EQ(Compression::parse("none").describe(), "none");
  EXPECT_EQ(Compression::parse("deflate").describe(), "shuffle+deflate:4");
  EXPECT_EQ(Compression::parse("deflate:9").describe(), "shuffle+deflate:9");
  EXPECT_THROW(Compression::parse("deflate:0"), UsageError);
  EXPECT_THROW(Compression::parse("zstd"), UsageError);
}

// A coefficient map written in row pieces out of order reads back exactly, zeros at masked pixels, with the basis
// kept beside it; writing before creating, past the last row, a NaN at a valid pixel or over an existing map are
// refused, and an uncommitted map leaves the store as it was.
TEST(Store, CoefficientMapsRoundTripInPiecesWithTheirBasis) {
  test::ScratchDir dir;
  const auto path = dir / "s.h5";
  constexpr std::size_t h = 9, w = 5, k = 3, b = 4;
  Basis basis;
  basis.method = "pca";
  basis.wavelengths = WavelengthGrid::range(400, 430, 10);
  basis.components = Eigen::MatrixXd::Random(k, b);
  basis.mean = Eigen::VectorXd::LinSpaced(b, 0.1, 0.4);
  std::vector<float> c(h * w * k);
  std::vector<std::uint8_t> mask(h * w, 1);
  for (std::size_t i = 0; i < c.size(); ++i) c[i] = float(i) * 0.25f - 7.0f;
  for (std::size_t p = 0; p < h * w; p += 4) mask[p] = 0;
  CoefficientsInfo info;
  info.image = "scene";
  info.basis = "b";
  info.height = h;
  info.width = w;
  info.valid_pixels = 33;
  info.chunk_rows = 4;
  {
    StoreWriter wr(path, {});
    EXPECT_THROW(wr.write_coefficient_rows("m", 0, 1, std::span<const float>(c.data(), w * k),
                                           std::span<const std::uint8_t>(mask.data(), w)),
                 UsageError);
    wr.create_coefficients("m", info, basis);
    auto rows = [&](std::size_t y0, std::size_t n) {
      wr.write_coefficient_rows("m", y0, n, std::span<const float>(c.data() + y0 * w * k, n * w * k),
                                std::span<const std::uint8_t>(mask.data() + y0 * w, n * w));
    };
    rows(4, 5);
    rows(0, 4);
    EXPECT_THROW(rows(8, 2), UsageError);
    std::vector<float> bad(c.begin(), c.begin() + std::ptrdiff_t(w * k));
    bad[k + 1] = std::numeric_limits<float>::infinity();  // pixel 1 is valid
    EXPECT_THROW(wr.write_coefficient_rows("m", 0, 1, bad, std::span<const std::uint8_t>(mask.data(), w)), InputError);
    bad[k + 1] = c[k + 1];
    bad[1] = std::nanf("");  // pixel 0 is masked: stored as zeros
    wr.write_coefficient_rows("m", 0, 1, bad, std::span<const std::uint8_t>(mask.data(), w));
    wr.commit();
  }
  const Store s = Store::open(path);
  EXPECT_EQ(s.coefficients(), std::vector<std::string>{"m"});
  const CoefficientsInfo got = s.coefficients_info("m");
  EXPECT_EQ(got.image, "scene");
  EXPECT_EQ(got.basis, "b");
  EXPECT_EQ(got.method, "pca");
  EXPECT_EQ(got.height, h);
  EXPECT_EQ(got.width, w);
  EXPECT_EQ(got.k, k);
  EXPECT_EQ(got.valid_pixels, 33u);
  EXPECT_EQ(got.chunk_rows, 4u);
  std::vector<float> back(h * w * k);
  std::vector<std::uint8_t> mback(h * w);
  s.read_coefficient_rows("m", 0, h, back, mback);
  EXPECT_EQ(mback, mask);
  for (std::size_t p = 0; p < h * w; ++p)
    for (std::size_t j = 0; j < k; ++j) EXPECT_EQ(back[p * k + j], mask[p] ? c[p * k + j] : 0.0f) << p << " " << j;
  std::vector<float> two(2 * w * k);
  s.read_coefficient_rows("m", 7, 2, two, {});
  EXPECT_TRUE(std::equal(two.begin(), two.end(), back.begin() + std::ptrdiff_t(7 * w * k)));
  EXPECT_THROW(s.read_coefficient_rows("m", 8, 2, two, {}), UsageError);
  const Basis kept = s.coefficients_basis("m");
  EXPECT_EQ(kept.components, basis.components);
  EXPECT_EQ(kept.mean, basis.mean);
  EXPECT_TRUE(kept.wavelengths.approx_equal(basis.wavelengths));
  EXPECT_NE(test::input_error_text([&] {
              s.coefficients_info("nope");
            }).find("no coefficient map 'nope' (coefficient maps: m)"),
            std::string::npos);

  const std::string before = test::read_bytes(path);
  {
    StoreWriter wr(path, {});
    EXPECT_NE(test::input_error_text([&] { wr.create_coefficients("m", info, basis); }).find("exists already"),
              std::string::npos);
    info.chunk_rows = 2;
    wr.create_coefficients("other", info, basis);  // never committed
  }
  EXPECT_EQ(test::read_bytes(path), before);
}
