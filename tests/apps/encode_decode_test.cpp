// The codec end to end: synth-brdf, encode (self and store bases), decode (file, store, .binary), brdf-diff,
// render under an environment, and the one-line errors that leave every file as it was.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "specula/codec/spectral_grid.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula::codec {
namespace {

using test::run_specula;

std::string q(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

TEST(CodecCli, EncodeDecodeAndDiffAGridWithItsOwnBasisAndWithALearnedOne) {
  test::ScratchDir dir;
  const auto grid = dir / "gold.spgrid", spc = dir / "gold.spc", back = dir / "back.spgrid";
  auto r = run_specula("synth-brdf gold --wavelengths 420:720:30 -o " + q(grid));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("encode " + q(grid) + " --basis self -k 3 --max-error 0.005 -o " + q(spc) + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"input_bytes", "output_bytes", "ratio", "seconds", "rms_error", "max_abs_error"})
    EXPECT_FALSE(std::isnan(test::json_number(r.output, key))) << key << ": " << r.output;
  EXPECT_EQ(test::json_number(r.output, "input_bytes"), 11.0 * brdf::kMerlCells * 8);
  EXPECT_EQ(test::json_number(r.output, "output_bytes"), double(std::filesystem::file_size(spc)));
  EXPECT_GT(test::json_number(r.output, "ratio"), 50);
  r = run_specula("decode " + q(spc) + " -o " + q(back));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("brdf-diff " + q(grid) + " " + q(back) + " --env default --size 48 --json --panel " +
                  q(dir / "panel.png"));
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"rms", "max_abs", "rel_rms_cos", "de00_mean", "de00_p95"})
    EXPECT_FALSE(std::isnan(test::json_number(r.output, key))) << key << ": " << r.output;
  EXPECT_LT(test::json_number(r.output, "de00_mean"), 0.5) << r.output;
  EXPECT_LT(test::json_number(r.output, "rel_rms_cos"), 0.02) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "panel.png"));
  // The decoded grid read back independently: every cell valid where the original is.
  const store::Grid a = read_grid_file(grid), b = read_grid_file(back);
  for (std::size_t c = 0; c < brdf::kMerlCells; c += 101) EXPECT_EQ(a.brdf[c] < 0, b.brdf[c] < 0) << c;

  // A basis learned from a database on the same bands, into a store and out as an RGB .binary.
  const auto db = dir / "db.h5";
  ASSERT_EQ(run_specula("-q synth-db -o " + q(db) + " --images 1 --size 40x50 --wavelengths 420:720:30").status, 0);
  ASSERT_EQ(run_specula("-q pca " + q(db) + " --name pca").status, 0);
  r = run_specula("encode " + q(grid) + " --basis " + q(db) + ":pca -k 4 -o " + q(dir / "db.spc") + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("decode " + q(dir / "db.spc") + " -o " + q(db) + ":gold");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(store::Store::open(db).grid_info("gold").bands, 11u);
  r = run_specula("decode " + q(dir / "db.spc") + " -o " + q(dir / "gold.binary"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(std::filesystem::file_size(dir / "gold.binary"), 12 + 3 * 8 * brdf::kMerlCells);
  r = run_specula("render " + q(back) + " --env default --size 32 -o " + q(dir / "env.png"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "env.exr"));
}

// Format 3 (the transform coder with its default grazing factor) end to end: coded to a rendered target, its JSON
// report checked against an independent brdf-diff of the decoded file, which is far smaller than format 1 at a similar
// rendered error.
TEST(CodecCli, ATargetEncodeMeetsItsTargetAsBrdfDiffMeasuresIt) {
  test::ScratchDir dir;
  const auto grid = dir / "rp.spgrid", spc = dir / "rp.spc", back = dir / "back.spgrid";
  ASSERT_EQ(run_specula("synth-brdf red-plastic --wavelengths 420:720:30 -o " + q(grid)).status, 0);
  auto r = run_specula("encode " + q(grid) + " --basis self -k 3 --target-de00 0.4 --target-p95 1.2 --trials 6 -o " +
                       q(spc) + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "format_version"), 3) << r.output;
  EXPECT_NE(r.output.find("\"reached\":true"), std::string::npos) << r.output;
  const double reached = test::json_number(r.output, "reached_de00_mean");
  ASSERT_EQ(run_specula("decode " + q(spc) + " -o " + q(back)).status, 0);
  r = run_specula("brdf-diff " + q(grid) + " " + q(back) + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LE(test::json_number(r.output, "de00_mean"), 0.4) << r.output;
  EXPECT_LE(test::json_number(r.output, "de00_p95"), 1.2) << r.output;
  EXPECT_LE(test::json_number(r.output, "worst_de00_mean"), 0.8) << r.output;
  EXPECT_NEAR(test::json_number(r.output, "de00_mean"), reached, 1e-3) << r.output;
  r = run_specula("encode " + q(grid) + " --basis self -k 3 --max-error 0.03 -o " + q(dir / "v1.spc"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_GT(std::filesystem::file_size(dir / "v1.spc"), 5 * std::filesystem::file_size(spc));
}

// Format 4 on a real measurement (Cornell acryl_blue, 1439 samples): the samples and their rule coded to a rendered
// target, judged by an independent brdf-diff of the decoded file against `specula resample` of the same samples by the
// same rule; a bad rule is one line and writes nothing.
TEST(CodecCli, SamplesCodedWithTheirRuleDecodeToTheirResample) {
  test::ScratchDir dir;
  const auto store = dir / "ab.h5", grid = dir / "ref.spgrid", spc = dir / "ab.spc", back = dir / "back.spgrid";
  ASSERT_EQ(
      run_specula("-q import " + q(std::filesystem::path(SPECULA_SHARED_DIR) / "data/brdf/cornell/acryl_blue.brdf") +
                  " -o " + q(store))
          .status,
      0);
  ASSERT_EQ(run_specula("-q resample " + q(store) + " acryl_blue --weights wendland -k 4 -o " + q(grid)).status, 0);
  auto r = run_specula("-q encode " + q(store) + ":acryl_blue --samples-rule weights=wendland,k=4 --basis self -k 16 " +
                       "--target-de00 0.5 --target-p95 1.5 --trials 6 -o " + q(spc) + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "format_version"), 4) << r.output;
  EXPECT_NE(r.output.find("\"method\":\"samples\""), std::string::npos) << r.output;
  EXPECT_LT(std::filesystem::file_size(spc), 40000u);
  ASSERT_EQ(run_specula("-q decode " + q(spc) + " -o " + q(back)).status, 0);
  r = run_specula("-q brdf-diff " + q(grid) + " " + q(back) + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LE(test::json_number(r.output, "de00_mean"), 0.5) << r.output;
  EXPECT_LE(test::json_number(r.output, "de00_p95"), 1.5) << r.output;
  EXPECT_EQ(test::json_number(r.output, "hole_cells"), 0) << r.output;  // exact angles, the same support
  for (const std::string rule : {"weights=gauss", "k=4,k=5", "k=0"}) {
    r = run_specula("-q encode " + q(store) + ":acryl_blue --samples-rule " + rule +
                    " --basis self -k 2 --step 0.1 -o " + q(dir / "bad.spc"));
    EXPECT_NE(r.status, 0) << rule;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << rule << ": " << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "bad.spc")) << rule;
  }
}

TEST(CodecCli, BadInputIsOneLineAndLeavesFilesAlone) {
  test::ScratchDir dir;
  const auto grid = dir / "m.spgrid", spc = dir / "m.spc";
  ASSERT_EQ(run_specula("synth-brdf green-matte --wavelengths 420:720:60 -o " + q(grid)).status, 0);
  ASSERT_EQ(run_specula("encode " + q(grid) + " --basis self -k 1 -o " + q(spc)).status, 0);
  const std::string before = test::read_bytes(spc);
  auto one_line = [](const test::RunResult& r) { return std::count(r.output.begin(), r.output.end(), '\n') == 1; };
  // A corrupt .spc.
  std::string bytes = before;
  bytes[bytes.size() / 2] ^= 0x40;
  { std::ofstream(dir / "bad.spc", std::ios::binary) << bytes; }
  auto r = run_specula("decode " + q(dir / "bad.spc") + " -o " + q(dir / "out.spgrid"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(one_line(r)) << r.output;
  EXPECT_NE(r.output.find("bad.spc"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.spgrid"));
  // A truncated one.
  { std::ofstream(dir / "short.spc", std::ios::binary) << before.substr(0, 50); }
  r = run_specula("decode " + q(dir / "short.spc") + " -o " + q(dir / "out.spgrid"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("truncated"), std::string::npos) << r.output;
  // A basis on other wavelengths, a bad -k, a bad --max-error, a store without a grid name: the .spc is untouched.
  const auto db = dir / "db.h5";
  ASSERT_EQ(run_specula("-q synth-db -o " + q(db) + " --images 1 --size 20x20").status, 0);
  ASSERT_EQ(run_specula("-q pca " + q(db) + " --name pca").status, 0);
  for (const std::string& args :
       {"--basis " + q(db) + ":pca -k 3", std::string("--basis self -k 9"),
        std::string("--basis self -k 1 --max-error 2"), std::string("--basis nowhere -k 1")}) {
    r = run_specula("encode " + q(grid) + " " + args + " -o " + q(spc));
    EXPECT_NE(r.status, 0) << args;
    EXPECT_TRUE(one_line(r)) << args << ": " << r.output;
  }
  r = run_specula("encode " + q(grid) + " --basis " + q(db) + ":pca -k 3 -o " + q(spc));
  EXPECT_NE(r.output.find("420-720 nm step 60"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_bytes(spc), before);
  r = run_specula("brdf-diff " + q(grid) + " " + q(db));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(":GRID"), std::string::npos) << r.output;
  r = run_specula("brdf-diff " + q(grid) + " " + q(grid) + " --size 2");
  EXPECT_EQ(r.status, 1) << r.output;
  // Format-2 options: exclusive, in range, and the .spc still untouched.
  for (const std::string& args :
       {std::string("--basis self -k 1 --step 0.1 --target-de00 0.5"), std::string("--basis self -k 1 --target-p95 1"),
        std::string("--basis self -k 1 --step 0"), std::string("--basis self -k 1 --target-de00 0.5 --trials 1"),
        std::string("--basis self -k 1 --target-de00 0.5 --env nowhere.exr"), std::string("--basis self --step 0.1"),
        std::string("--basis self --max-error 0.01")}) {
    r = run_specula("encode " + q(grid) + " " + args + " -o " + q(spc));
    EXPECT_NE(r.status, 0) << args;
    EXPECT_TRUE(one_line(r)) << args << ": " << r.output;
  }
  EXPECT_EQ(test::read_bytes(spc), before);
  r = run_specula("synth-brdf velvet -o " + q(dir / "v.spgrid"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("red-plastic"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace specula::codec
