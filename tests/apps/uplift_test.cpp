#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "specula/codec/merl.h"
#include "specula/codec/spectral_grid.h"
#include "specula/store/io/exr.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula {
namespace {

constexpr std::size_t N = brdf::kMerlCells;

std::size_t files_in(const std::filesystem::path& dir) {
  return std::size_t(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()));
}

TEST(UpliftCli, TruncatedBinaryIsOneLineAndLeavesNoOutput) {
  test::ScratchDir dir;
  const auto in = dir / "red.binary";
  codec::write_merl(in, codec::MerlBrdf());
  std::filesystem::resize_file(in, 20000000);
  for (const std::string& out :
       {"-o '" + (dir / "out.spgrid").string() + "'", "--store '" + (dir / "s.h5").string() + "' --name red"}) {
    const test::RunResult r = test::run_specula("-q uplift '" + in.string() + "' " + out);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_EQ(r.output.rfind("specula: ", 0), 0u) << r.output;
    EXPECT_NE(r.output.find(in.string()), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("20000000 bytes, expected 34992012 bytes"), std::string::npos) << r.output;
    EXPECT_EQ(files_in(dir.path()), 1u);  // only the input: no output, no temporary
  }
}

TEST(UpliftCli, NeedsExactlyOneDestination) {
  test::ScratchDir dir;
  const auto in = dir / "a.binary";
  codec::write_merl(in, codec::MerlBrdf());
  test::RunResult r = test::run_specula("-q uplift '" + in.string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("either -o FILE"), std::string::npos) << r.output;
  r = test::run_specula("-q uplift '" + in.string() + "' --store '" + (dir / "s.h5").string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--store needs --name"), std::string::npos) << r.output;
  r = test::run_specula("-q uplift '" + in.string() + "' -o '" + (dir / "x.spgrid").string() + "' --alpha -1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("alpha is -1"), std::string::npos) << r.output;
  EXPECT_EQ(files_in(dir.path()), 1u);
}

// Grey and pastel cells (inside the sRGB gamut) come back to their RGB through export; the file and the
// store hold the same 31-band grid.
TEST(UpliftCli, FileAndStoreRoundTripToRgb) {
  test::ScratchDir dir;
  codec::MerlBrdf rgb;
  std::vector<std::size_t> cells;
  for (std::size_t cell = 5; cell < N; cell += 7919) {
    const double t = double(cell) / double(N);
    rgb.set(cell, Eigen::Vector3d(0.2 + 0.3 * t, 0.25, 0.3 - 0.1 * t));
    cells.push_back(cell);
  }
  const auto in = dir / "pastel.binary", out = dir / "pastel.spgrid", st = dir / "s.h5";
  codec::write_merl(in, rgb);
  test::RunResult r = test::run_specula("-q uplift '" + in.string() + "' -o '" + out.string() + "' --nonnegative");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("uplifted " + std::to_string(cells.size()) + " cells"), std::string::npos) << r.output;
  // The store variant on a coarser grid keeps the test fast.
  r = test::run_specula("-q uplift '" + in.string() + "' --store '" + st.string() +
                        "' --name pastel --wavelengths 400:700:50");
  ASSERT_EQ(r.status, 0) << r.output;

  const store::Grid g = codec::read_grid_file(out);
  ASSERT_EQ(g.bands(), 31u);
  const store::Grid gs = store::Store::open(st).read_grid("pastel");
  ASSERT_EQ(gs.bands(), 7u);
  for (const store::Grid* grid : {&g, &gs}) {
    const codec::RgbExport back =
        codec::grid_to_merl(*grid, codec::rgb_weights(grid->wavelengths, illuminant("D65", grid->wavelengths)));
    for (std::size_t cell : cells)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(back.brdf.value(c, cell), rgb.value(c, cell), 1e-6) << cell;
    EXPECT_FALSE(back.brdf.has_data(6));
  }
}

// An RGB environment map becomes a spectral EXR of emission whose RGB (equal-energy white) is the input.
TEST(UpliftCli, AnRgbEnvironmentMapBecomesASpectralExrWithTheSameRgb) {
  test::ScratchDir dir;
  std::vector<float> rgb;
  for (std::size_t p = 0; p < 16 * 8; ++p)
    for (const float v : {0.2f + 0.01f * float(p % 16), 0.4f, 0.3f + 0.02f * float(p / 16)}) rgb.push_back(v);
  store::write_exr_rgb(dir / "sky.exr", 16, 8, rgb);
  std::size_t w = 0, h = 0;
  const std::vector<float> stored = store::read_exr_rgb(dir / "sky.exr", w, h);  // as rounded to half floats
  auto r = test::run_specula("uplift '" + (dir / "sky.exr").string() + "' -o '" + (dir / "sky-spectral.exr").string() +
                             "' --nonnegative --wavelengths 400:700:10");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Cube cube = store::read_spectral_exr(dir / "sky-spectral.exr");
  ASSERT_EQ(cube.bands, 31u);
  EXPECT_EQ(cube.units, "radiance");
  const auto weights = codec::rgb_weights(cube.wavelengths, Eigen::VectorXd::Ones(31));
  for (std::size_t p = 0; p < 16 * 8; ++p) {
    const Eigen::Map<const Eigen::VectorXf> s(cube.data.data() + p * 31, 31);
    const Eigen::Vector3d back = weights * s.cast<double>();
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back[c], stored[3 * p + std::size_t(c)], 1e-5) << p;
    EXPECT_GE(s.minCoeff(), 0.0f);
  }
  // The spectral map lights a rendering.
  ASSERT_EQ(
      test::run_specula("synth-brdf green-matte --wavelengths 400:700:10 -o '" + (dir / "g.spgrid").string() + "'")
          .status,
      0);
  r = test::run_specula("render '" + (dir / "g.spgrid").string() + "' --size 16 --env '" +
                        (dir / "sky-spectral.exr").string() + "' -o '" + (dir / "g.png").string() + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  // A negative pixel, or a non-EXR output: one line, nothing written.
  rgb[7] = -0.5f;
  store::write_exr_rgb(dir / "bad.exr", 16, 8, rgb);
  r = test::run_specula("uplift '" + (dir / "bad.exr").string() + "' -o '" + (dir / "bad-s.exr").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("bad.exr"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad-s.exr"));
  r = test::run_specula("uplift '" + (dir / "sky.exr").string() + "' -o '" + (dir / "sky.spgrid").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
}

}  // namespace
}  // namespace specula
