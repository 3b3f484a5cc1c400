#include "specula/codec/spectral_grid.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "specula/codec/grid_files.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;

store::Grid random_grid(std::size_t bands, unsigned seed) {
  store::Grid g;
  std::vector<double> nm;
  for (std::size_t k = 0; k < bands; ++k) nm.push_back(400.0 + 13.5 * double(k));
  g.wavelengths = WavelengthGrid(nm);
  g.scale = 1.0 / 1500;
  g.brdf.resize(bands * N);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1000.0f);
  for (float& v : g.brdf) v = u(rng);
  return g;
}

// Patches bytes of a file and rewrites its CRC-32 so that only the field under test is wrong.
void patch(const std::filesystem::path& p, std::size_t offset, const void* data, std::size_t n) {
  std::string bytes = test::read_bytes(p);
  std::memcpy(bytes.data() + offset, data, n);
  const auto crc = std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(bytes.data()), uInt(bytes.size() - 4)));
  std::memcpy(bytes.data() + bytes.size() - 4, &crc, 4);
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
}

TEST(GridFile, RoundTripAndDocumentedLayout) {
  test::ScratchDir dir;
  const store::Grid g = random_grid(2, 1);
  const auto p = dir / "g.spgrid";
  write_grid_file(p, g);
  const std::string bytes = test::read_bytes(p);
  ASSERT_EQ(bytes.size(), 40u + 16 + 8 * N + 4);
  EXPECT_EQ(bytes.substr(0, 8), "SPECGRID");
  std::uint32_t u32[6];
  std::memcpy(u32, bytes.data() + 8, sizeof u32);
  EXPECT_EQ(u32[0], 1u);  // version
  EXPECT_EQ(u32[1], 2u);  // bands
  EXPECT_EQ(u32[2], 90u);
  EXPECT_EQ(u32[3], 90u);
  EXPECT_EQ(u32[4], 180u);
  EXPECT_EQ(u32[5], 0u);  // flags
  double d[3];
  std::memcpy(d, bytes.data() + 32, sizeof d);
  EXPECT_EQ(d[0], 1.0 / 1500);
  EXPECT_EQ(d[1], 400.0);
  EXPECT_EQ(d[2], 413.5);
  float v;
  std::memcpy(&v, bytes.data() + 56 + 4 * (N + 777), 4);
  EXPECT_EQ(v, g.brdf[N + 777]);
  std::uint32_t crc;
  std::memcpy(&crc, bytes.data() + bytes.size() - 4, 4);
  EXPECT_EQ(crc, std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(bytes.data()), uInt(bytes.size() - 4))));

  const store::Grid r = read_grid_file(p);
  EXPECT_EQ(r.brdf, g.brdf);
  EXPECT_EQ(r.scale, g.scale);
  EXPECT_TRUE(r.wavelengths.approx_equal(g.wavelengths, 0));
}

TEST(GridFile, EveryFieldIsValidated) {
  test::ScratchDir dir;
  const auto good = dir / "good.spgrid", p = dir / "p.spgrid";
  write_grid_file(good, random_grid(1, 2));
  auto fresh = [&] { std::filesystem::copy_file(good, p, std::filesystem::copy_options::overwrite_existing); };
  auto error = [&] { return test::input_error_text([&] { read_grid_file(p); }); };
  auto expect = [&](const std::string& what) {
    const std::string msg = error();
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  };
  fresh();
  std::filesystem::resize_file(p, 30);
  expect("30 bytes, shorter than the 40-byte header");
  fresh();
  std::filesystem::resize_file(p, 1000);
  expect("truncated spectral grid: 1000 bytes, expected " + std::to_string(grid_file_bytes(1)));
  fresh();
  patch(p, 0, "SPECGRIX", 8);
  expect("does not begin with \"SPECGRID\"");
  const std::uint32_t two = 2, zero = 0, big = 5000, dim = 360, flag = 1;
  fresh();
  patch(p, 8, &two, 4);
  expect("version 2 is not one this specula reads");
  fresh();
  patch(p, 12, &zero, 4);
  expect("declares 0 bands");
  fresh();
  patch(p, 12, &big, 4);
  expect("declares 5000 bands");
  fresh();
  patch(p, 12, &two, 4);
  expect("expected " + std::to_string(grid_file_bytes(2)) + " for 2 bands");
  fresh();
  patch(p, 24, &dim, 4);
  expect("dimensions 90 x 90 x 360");
  fresh();
  patch(p, 28, &flag, 4);
  expect("flags are 1");
  const double nan = std::nan(""), neg = -1;
  fresh();
  patch(p, 32, &nan, 8);
  expect("scale is nan");
  fresh();
  patch(p, 32, &neg, 8);
  expect("scale is -1");
  fresh();
  patch(p, 40, &neg, 8);
  expect("wavelengths");
  const float fnan = std::nanf("");
  fresh();
  patch(p, 48 + 4 * 99, &fnan, 4);
  expect("non-finite value at band 0, cell 99");
  // A flipped bit without a matching CRC is caught.
  fresh();
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(48 + 4 * 5000);
    f.put('\x7f');
  }
  expect("corrupt: CRC-32");
  EXPECT_THROW(read_grid_file(dir / "missing.spgrid"), InputError);
}

TEST(GridExport, FlatSpectrumIsGreyUnderEveryIlluminant) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 10);
  for (const char* name : {"D65", "A", "E"}) {
    const auto w = rgb_weights(grid, illuminant(name, grid));
    const Eigen::Vector3d rgb = w * Eigen::VectorXd::Constant(31, 0.3);
    EXPECT_LT((rgb - Eigen::Vector3d::Constant(0.3)).cwiseAbs().maxCoeff(), 1e-12) << name;
  }
}

// A Lambertian grid with a flat albedo exports to rho / pi in every channel at every cell with data,
// and to no data below the horizon; a narrow-band spectrum lies outside the sRGB gamut and is clamped.
TEST(GridExport, LambertianGridToMerl) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 50);
  const brdf::Lambertian lam(grid, Eigen::VectorXd::Constant(7, 0.6));
  store::Grid g;
  g.wavelengths = grid;
  g.scale = 0.5;
  g.brdf.resize(7 * N);
  brdf::evaluate_grid(lam, g.brdf);
  for (float& v : g.brdf)
    if (v >= 0) v *= 2;  // stored values times scale 0.5 give 1/sr
  const RgbExport out = grid_to_merl(g, rgb_weights(grid, illuminant("D65", grid)));
  EXPECT_EQ(out.clamped, 0u);
  std::size_t with_data = 0;
  for (std::size_t cell = 0; cell < N; ++cell) {
    const bool valid = brdf::merl_cell_valid(brdf::merl_cell(cell));
    ASSERT_EQ(out.brdf.has_data(cell), valid) << cell;
    if (!valid) continue;
    ++with_data;
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(out.brdf.value(c, cell), 0.6 / M_PI, 1e-6);
  }
  EXPECT_GT(with_data, N / 4);

  store::Grid blue = g;
  for (std::size_t cell = 0; cell < N; ++cell)
    for (std::size_t k = 0; k < 7; ++k)
      blue.brdf[k * N + cell] = (k == 1 && g.brdf[cell] >= 0) ? 1.0f : (g.brdf[cell] >= 0 ? 0.0f : -1.0f);
  const RgbExport b = grid_to_merl(blue, rgb_weights(grid, illuminant("D65", grid)));
  EXPECT_GT(b.clamped, 0u);
  for (std::size_t cell = 0; cell < N; cell += 101)
    if (b.brdf.has_data(cell)) {
      ASSERT_GE(b.brdf.stored(0, cell), 0.0);
    }
  EXPECT_THROW(grid_to_merl(g, Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, 6)), UsageError);
}

store::Grid flat_grid(std::size_t bands, float value) {
  store::Grid g;
  g.wavelengths = WavelengthGrid::range(400, 400 + 10 * double(bands - 1), 10);
  g.brdf.assign(bands * brdf::kMerlCells, value);
  return g;
}

TEST(GridFile, SeveralFilesAppearAllOrNone) {
  test::ScratchDir dir;
  const store::Grid brdf = flat_grid(3, 0.125f), conf = flat_grid(1, 0.75f);
  store::Grid bad = conf;
  bad.brdf.pop_back();
  const auto a = dir / "x.spgrid", b = dir / "x.confidence.spgrid";
  const auto files_in = [&] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path())) ++n;
    return n;
  };
  {  // the second grid is malformed: nothing is written
    const std::pair<std::filesystem::path, const store::Grid*> files[] = {{a, &brdf}, {b, &bad}};
    EXPECT_THROW(write_grid_files(files), UsageError);
  }
  EXPECT_EQ(files_in(), 0u);
  {  // the second cannot be created (its directory is missing): the first, already written, is not left behind
    const std::pair<std::filesystem::path, const store::Grid*> files[] = {{a, &brdf}, {dir / "no" / "c.spgrid", &conf}};
    EXPECT_ANY_THROW(write_grid_files(files));
  }
  EXPECT_EQ(files_in(), 0u);
  const std::pair<std::filesystem::path, const store::Grid*> files[] = {{a, &brdf}, {b, &conf}};
  write_grid_files(files);
  EXPECT_EQ(files_in(), 2u);
  EXPECT_EQ(read_grid_file(a).brdf, brdf.brdf);
  EXPECT_EQ(read_grid_file(b).brdf, conf.brdf);
}

}  // namespace
}  // namespace specula::codec
