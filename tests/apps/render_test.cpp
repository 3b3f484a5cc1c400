#include <gtest/gtest.h>

#include <algorithm>

#include "specula/codec/merl.h"
#include "specula/codec/spc.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula::codec {
namespace {

// The spectral grid file, the same grid in a store, and its RGB export as a .binary render to the same picture.
TEST(RenderCli, GridFileStoreGridAndBinaryAgree) {
  test::ScratchDir dir;
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 50);
  Eigen::VectorXd rho_d(7);
  rho_d << 0.05, 0.1, 0.2, 0.4, 0.6, 0.6, 0.5;  // orange
  const brdf::Ward ward(grid, rho_d, Eigen::VectorXd::Constant(7, 0.3), Eigen::VectorXd::Constant(7, 0.1));
  store::Grid g;
  g.wavelengths = grid;
  g.brdf.resize(7 * brdf::kMerlCells);
  brdf::evaluate_grid(ward, g.brdf);
  write_grid_file(dir / "ward.spgrid", g);
  {
    store::StoreWriter w(dir / "s.h5", {.compression = store::Compression::parse("none")});
    w.add_grid("ward", g);
    w.commit();
  }
  write_merl(dir / "ward.binary", grid_to_merl(g, rgb_weights(grid, illuminant("D65", grid))).brdf);
  const std::string inputs[] = {(dir / "ward.spgrid").string(), (dir / "s.h5").string() + ":ward",
                                (dir / "ward.binary").string()};
  const std::string outputs[] = {"a", "b", "c"};
  for (int i = 0; i < 3; ++i) {
    const test::RunResult r = test::run_specula("-q render '" + inputs[i] + "' -o '" +
                                                (dir / (outputs[i] + ".png")).string() + "' --size 48 --light 30,120");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_TRUE(std::filesystem::exists(dir / (outputs[i] + ".exr")));
  }
  const store::PngImage a = store::read_png(dir / "a.png");
  EXPECT_EQ(a.width, 48u);
  EXPECT_EQ(a.height, 48u);
  EXPECT_EQ(a.channels, 3u);
  EXPECT_EQ(a.samples, store::read_png(dir / "b.png").samples);
  EXPECT_EQ(a.samples, store::read_png(dir / "c.png").samples);
  // Orange: at the lit centre red exceeds blue.
  const std::size_t centre = 3 * (24 * 48 + 24);
  EXPECT_GT(a.samples[centre], a.samples[centre + 2]);

  const test::RunResult bad =
      test::run_specula("-q render '" + inputs[0] + "' -o '" + (dir / "x.png").string() + "' --light 95,0");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.output.find("--light THETA,PHI"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
  const test::RunResult bare =
      test::run_specula("-q render '" + (dir / "s.h5").string() + "' -o '" + (dir / "x.png").string() + "'");
  EXPECT_EQ(bare.status, 1);
  EXPECT_NE(bare.output.find("s.h5:GRID"), std::string::npos) << bare.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
}

// Under an environment: a grey Lambertian in a uniform white RGB map (uplifted to a flat spectrum) shows its
// albedo in the linear EXR, since the rendering's white (a white Lambertian facing the viewer) maps to 1; the
// viewer-facing pixel of an odd-sized sphere is exact (see environment_test.cpp), the rest within the
// quadrature's 3.8 %. An RGB .binary is uplifted first; a bad map is one line and writes nothing.
TEST(RenderCli, UnderAnEnvironmentAGreyShowsItsAlbedo) {
  test::ScratchDir dir;
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 10);
  store::Grid g;
  g.wavelengths = grid;
  g.brdf.resize(31 * brdf::kMerlCells);
  brdf::evaluate_grid(brdf::Lambertian(grid, Eigen::VectorXd::Constant(31, 0.5)), g.brdf);
  write_grid_file(dir / "grey.spgrid", g);
  write_merl(dir / "grey.binary", grid_to_merl(g, rgb_weights(grid, illuminant("D65", grid))).brdf);
  store::write_exr_rgb(dir / "white.exr", 16, 8, std::vector<float>(3 * 16 * 8, 1.0f));
  for (const char* input : {"grey.spgrid", "grey.binary"}) {
    const auto r = test::run_specula("render '" + (dir / input).string() + "' --env '" + (dir / "white.exr").string() +
                                     "' --size 33 -o '" + (dir / "g.png").string() + "'");
    ASSERT_EQ(r.status, 0) << r.output;
    std::size_t w = 0, h = 0;
    const std::vector<float> linear = store::read_exr_rgb(dir / "g.exr", w, h);
    ASSERT_EQ(w, 33u);
    const std::size_t centre = 3 * (16 * 33 + 16);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(linear[centre + std::size_t(c)], 0.5, 2e-3) << input;  // half floats
    for (std::size_t p = 0; p < 33 * 33; ++p) {
      const double x = (double(p % 33) + 0.5) / 16.5 - 1, y = (double(p / 33) + 0.5) / 16.5 - 1;
      if (x * x + y * y >= 0.9) continue;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(linear[3 * p + std::size_t(c)], 0.5, 0.5 * 0.039) << input << " " << p;
    }
  }
  std::vector<float> bad(3 * 16 * 8, 1.0f);
  bad[40] = -2;
  store::write_exr_rgb(dir / "bad.exr", 16, 8, bad);
  const auto r = test::run_specula("render '" + (dir / "grey.spgrid").string() + "' --env '" +
                                   (dir / "bad.exr").string() + "' -o '" + (dir / "x.png").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_NE(r.output.find("bad.exr: pixel (13, 0)"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "x.exr"));
}

// A .spc renders from its coefficients to the picture of its decoded grid, under a directional light and under
// an environment; commands that need a grid (brdf-diff) take a .spc by decoding it.
TEST(RenderCli, ASpcRendersAsItsDecodedGrid) {
  test::ScratchDir dir;
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 50);
  const brdf::Ward ward(grid, Eigen::VectorXd::LinSpaced(7, 0.05, 0.5), Eigen::VectorXd::Constant(7, 0.2),
                        Eigen::VectorXd::Constant(7, 0.15));
  store::Grid g;
  g.wavelengths = grid;
  g.brdf.resize(7 * brdf::kMerlCells);
  brdf::evaluate_grid(ward, g.brdf);
  const auto bytes = encode_spc(g, self_basis(g, 3), {.max_error = 0.01});
  write_spc_file(dir / "w.spc", bytes);
  write_grid_file(dir / "w.spgrid", decode_spc(bytes, "w.spc"));
  for (const std::string light : {"--light 30,120", "--env default"}) {
    for (const std::string name : {"w.spc", "w.spgrid"}) {
      const test::RunResult r = test::run_specula("-q render '" + (dir / name).string() + "' -o '" +
                                                  (dir / (name + ".png")).string() + "' --size 40 " + light);
      ASSERT_EQ(r.status, 0) << r.output;
    }
    EXPECT_EQ(store::read_png(dir / "w.spc.png").samples, store::read_png(dir / "w.spgrid.png").samples) << light;
  }
  const test::RunResult d = test::run_specula("-q brdf-diff '" + (dir / "w.spc").string() + "' '" +
                                              (dir / "w.spgrid").string() + "' --env default --json");
  ASSERT_EQ(d.status, 0) << d.output;
  EXPECT_EQ(test::json_number(d.output, "rms"), 0) << d.output;
  const test::RunResult suite =
      test::run_specula("-q brdf-diff '" + (dir / "w.spc").string() + "' '" + (dir / "w.spgrid").string() + "' --json");
  ASSERT_EQ(suite.status, 0) << suite.output;
  EXPECT_EQ(test::json_number(suite.output, "de00_max"), 0) << suite.output;
  EXPECT_EQ(test::json_number(suite.output, "rel_rms_cos"), 0) << suite.output;
}

}  // namespace
}  // namespace specula::codec
