// specula brdf-diff end to end: its JSON against closed forms, RGB .binary inputs, the maps it writes, and the
// one-line errors that write nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "test_support.h"

namespace specula::codec {
namespace {

using test::run_specula;

std::string q(const std::filesystem::path& p) { return "'" + p.string() + "'"; }
bool one_line(const test::RunResult& r) { return std::count(r.output.begin(), r.output.end(), '\n') == 1; }

const WavelengthGrid kGrid = WavelengthGrid::range(420, 720, 60);

store::Grid ward(double scale = 1) {
  store::Grid g;
  g.wavelengths = kGrid;
  g.brdf.resize(kGrid.size() * brdf::kMerlCells);
  brdf::evaluate_grid(brdf::Ward(kGrid, Eigen::VectorXd::LinSpaced(6, 0.1, 0.5), Eigen::VectorXd::Constant(6, 0.2),
                                 Eigen::VectorXd::Constant(6, 0.15)),
                      g.brdf);
  for (auto& v : g.brdf)
    if (v >= 0) v = float(double(v) * scale);
  return g;
}

TEST(BrdfDiffCli, IdenticalGridsGiveZerosAndAScaledOneItsScale) {
  test::ScratchDir dir;
  write_grid_file(dir / "a.spgrid", ward());
  write_grid_file(dir / "b.spgrid", ward(1.01));
  auto r =
      run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "a.spgrid") + " --env default --size 24 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(one_line(r)) << r.output;
  for (const char* key : {"rms", "max_abs", "rel_rms_cos", "de00_mean", "de00_p95", "de00_max", "only_a", "only_b"})
    EXPECT_EQ(test::json_number(r.output, key), 0.0) << key << ": " << r.output;
  EXPECT_GT(test::json_number(r.output, "cells"), 1e6);
  r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "b.spgrid") +
                  " --env default --size 24 --json --heatmap " + q(dir / "h.png") + " --panel " + q(dir / "p.png"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NEAR(test::json_number(r.output, "rel_rms_cos"), 0.01, 1e-6) << r.output;
  EXPECT_GT(test::json_number(r.output, "de00_mean"), 0) << r.output;
  EXPECT_EQ(store::read_png(dir / "h.png").width, 24u);
  EXPECT_EQ(store::read_png(dir / "p.png").width, 72u);
  // The text report names both inputs and the environment.
  r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "b.spgrid") + " --env default --size 16");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("b.spgrid"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("built-in"), std::string::npos) << r.output;
}

// By default the lighting suite: every condition in the JSON, holes counted, the worst condition's panel.
TEST(BrdfDiffCli, ReportsTheLightingSuiteByDefault) {
  test::ScratchDir dir;
  write_grid_file(dir / "a.spgrid", ward());
  write_grid_file(dir / "b.spgrid", ward(1.01));
  store::Grid holed = ward();
  std::size_t removed = 0;
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c)
    if (brdf::merl_cell(c).theta_h < 10 && holed.brdf[c] >= 0) {
      ++removed;
      for (std::size_t k = 0; k < kGrid.size(); ++k) holed.brdf[k * brdf::kMerlCells + c] = -1;
    }
  write_grid_file(dir / "h.spgrid", holed);
  auto r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "a.spgrid") + " --size 24 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(one_line(r)) << r.output;
  for (const char* key : {"de00_mean", "de00_p95", "de00_max", "hole_cells", "rel_rms_cos"})
    EXPECT_EQ(test::json_number(r.output, key), 0.0) << key << ": " << r.output;
  std::size_t conditions = 0;
  for (auto at = r.output.find("\"elevation_deg\""); at != std::string::npos;
       at = r.output.find("\"elevation_deg\"", at + 1))
    ++conditions;
  EXPECT_EQ(conditions, 38u) << r.output;
  r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "b.spgrid") + " --size 24 --json --panel " +
                  q(dir / "p.png"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NEAR(test::json_number(r.output, "rel_rms_cos"), 0.01, 1e-6) << r.output;
  EXPECT_GT(test::json_number(r.output, "de00_mean"), 0) << r.output;
  EXPECT_EQ(store::read_png(dir / "p.png").width, 72u);
  r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "h.spgrid") + " --size 24 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "hole_cells"), double(removed)) << r.output;
  EXPECT_GT(test::json_number(r.output, "hole_pixels"), 0) << r.output;
  r = run_specula("brdf-diff " + q(dir / "a.spgrid") + " " + q(dir / "h.spgrid") + " --size 24");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("lighting suite"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("worst condition"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(std::to_string(removed) + " of the reference's"), std::string::npos) << r.output;
}

// An RGB .binary is uplifted onto the other grid's bands exactly as `specula uplift` does by default, so it and
// the uplifted file are the same grid; an RGB EXR lights the comparison as well.
TEST(BrdfDiffCli, AnRgbBinaryIsUpliftedOntoTheOtherGridsBands) {
  test::ScratchDir dir;
  ASSERT_EQ(run_specula("-q synth-brdf blue-paint --wavelengths 420:720:60 -o " + q(dir / "p.binary")).status, 0);
  ASSERT_EQ(
      run_specula("-q uplift " + q(dir / "p.binary") + " --wavelengths 420:720:60 -o " + q(dir / "p.spgrid")).status,
      0);
  std::vector<float> rgb;
  for (std::size_t p = 0; p < 32 * 16; ++p)
    for (const float v : {0.4f, 0.5f, p < 16 * 16 ? 0.9f : 0.2f}) rgb.push_back(v);
  store::write_exr_rgb(dir / "sky.exr", 32, 16, rgb);
  for (const std::string& args :
       {q(dir / "p.binary") + " " + q(dir / "p.spgrid"), q(dir / "p.spgrid") + " " + q(dir / "p.binary")}) {
    const auto r = run_specula("brdf-diff " + args + " --size 16 --json --env " + q(dir / "sky.exr"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(test::json_number(r.output, "max_abs"), 0.0) << r.output;
    EXPECT_EQ(test::json_number(r.output, "de00_max"), 0.0) << r.output;
    EXPECT_NE(r.output.find("sky.exr"), std::string::npos) << r.output;
  }
}

TEST(BrdfDiffCli, BadInputIsOneLineAndWritesNothing) {
  test::ScratchDir dir;
  write_grid_file(dir / "a.spgrid", ward());
  store::Grid other = ward();
  other.wavelengths = WavelengthGrid::range(400, 700, 60);
  write_grid_file(dir / "o.spgrid", other);
  std::vector<float> rgb(3 * 8 * 4, 0.5f);
  rgb[7] = std::nanf("");
  store::write_exr_rgb(dir / "nan.exr", 8, 4, rgb);
  { std::ofstream(dir / "junk.exr", std::ios::binary) << "not an OpenEXR file"; }
  const std::string a = q(dir / "a.spgrid"), h = " --heatmap " + q(dir / "h.png");
  struct Case {
    std::string args, expect;
  };
  for (const Case& c :
       {Case{a + " " + q(dir / "missing.spgrid") + h, "missing.spgrid"},
        Case{a + " " + q(dir / "o.spgrid") + h, "o.spgrid has 6 bands 400-700"},
        Case{a + " " + a + " --size 2" + h, "--size 2"}, Case{a + " " + a + " --size 5000" + h, "--size 5000"},
        Case{a + " " + a + " --size many" + h, "--size"},
        Case{a + " " + a + " --env " + q(dir / "junk.exr") + h, "junk.exr"},
        Case{a + " " + a + " --env " + q(dir / "none.exr") + h, "none.exr"},
        Case{a + " " + a + " --env " + q(dir / "nan.exr") + h, "nan.exr"},
        Case{a + " " + a + " --heatmap " + q(dir / "h.jpg"), "--heatmap"}, Case{a + " " + q(dir / "s.h5") + h, ""}}) {
    const auto r = run_specula("brdf-diff " + c.args);
    EXPECT_NE(r.status, 0) << c.args;
    // CLI11's own parse errors add a second line pointing to --help (every command does).
    if (c.args.find("many") == std::string::npos) {
      EXPECT_TRUE(one_line(r)) << c.args << ": " << r.output;
    }
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << ": " << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "h.png")) << c.args;
  }
}

}  // namespace
}  // namespace specula::codec
