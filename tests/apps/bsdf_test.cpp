// RGL .bsdf through the CLI: export with scenes, import into a store, render and brdf-diff of the file, and
// malformed files refused with one line and exit 1, the store left as it was.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "specula/codec/rgl_bsdf.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

std::string q(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

}  // namespace

TEST(BsdfCli, ExportImportRenderAndDiff) {
  test::ScratchDir dir;
  const auto grid = dir / "paint.spgrid";
  auto r = run_specula("synth-brdf blue-paint --wavelengths 400:700:50 -o " + q(grid));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("export " + q(grid) + " -o " + q(dir / "paint.bsdf") + " --scene pbrt --scene mitsuba");
  ASSERT_EQ(r.status, 0) << r.output;
  const codec::RglBsdf b = codec::read_rgl_bsdf(dir / "paint.bsdf");
  EXPECT_FALSE(b.rgb);
  EXPECT_EQ(b.wavelengths.size(), 7u);
  EXPECT_NE(test::read_bytes(dir / "paint.pbrt").find("Material \"measured\" \"string filename\" [ \"paint.bsdf\" ]"),
            std::string::npos);
  EXPECT_NE(test::read_bytes(dir / "paint.xml")
                .find("<bsdf type=\"measured\"><string name=\"filename\" value=\"paint.bsdf\"/>"),
            std::string::npos);
  EXPECT_NE(test::read_bytes(dir / "paint.xml").find("scalar_spectral"), std::string::npos);

  r = run_specula("import " + q(dir / "paint.bsdf") + " -o " + q(dir / "s.h5") + " --name back");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(store::Store::open(dir / "s.h5").read_grid("back").bands(), 7u);

  r = run_specula("brdf-diff " + q(grid) + " " + q(dir / "paint.bsdf") + " --json --size 64");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LT(test::json_number(r.output, "de00_mean"), 0.5);

  r = run_specula("render " + q(dir / "paint.bsdf") + " -o " + q(dir / "paint.png") + " --size 32");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "paint.png"));

  r = run_specula("export " + q(grid) + " -o " + q(dir / "rgb.bsdf") + " --rgb --scene pbrt");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("pbrt-v4 reads spectral .bsdf files only"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "rgb.bsdf"));
  r = run_specula("export " + q(grid) + " -o " + q(dir / "rgb.bsdf") + " --rgb");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(codec::read_rgl_bsdf(dir / "rgb.bsdf").rgb);
  r = run_specula("render " + q(dir / "rgb.bsdf") + " -o " + q(dir / "rgb.png") + " --size 32");
  ASSERT_EQ(r.status, 0) << r.output;
}

TEST(BsdfCli, ExportToATargetReportsTheResolutionsTried) {
  test::ScratchDir dir;
  const auto grid = dir / "paint.spgrid";
  auto r = run_specula("synth-brdf blue-paint --wavelengths 400:700:50 -o " + q(grid));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("export " + q(grid) + " -o " + q(dir / "t.bsdf") + " --target-de00 0.5");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("8 theta_i x 32^2 samples"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("(meets the target)"), std::string::npos) << r.output;
  EXPECT_EQ(codec::read_rgl_bsdf(dir / "t.bsdf").theta_i.size(), 8u);
  r = run_specula("export " + q(grid) + " -o " + q(dir / "u.bsdf") + " --target-de00 0.5 --rgb");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("drop --rgb"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "u.bsdf"));
}

TEST(BsdfCli, ImportKeepsTheSourceParameterisationAndExportSaysWhichItUsed) {
  test::ScratchDir dir;
  const auto grid = dir / "paint.spgrid";
  auto r = run_specula("synth-brdf blue-paint --wavelengths 400:700:50 -o " + q(grid));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("export " + q(grid) + " -o " + q(dir / "src.bsdf") + " --theta-i 4 --resolution 12");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("estimate parameterisation"), std::string::npos) << r.output;
  const codec::RglBsdf src = codec::read_rgl_bsdf(dir / "src.bsdf");
  r = run_specula("import " + q(dir / "src.bsdf") + " -o " + q(dir / "s.h5") + " --name back");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto kept = store::Store::open(dir / "s.h5").read_grid("back").parameterisation;
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->theta_i, src.theta_i);
  EXPECT_EQ(kept->resolution, 12u);

  const std::string back = q(dir / "s.h5") + ":back";
  r = run_specula("export " + back + " -o " + q(dir / "again.bsdf") + " --parameterisation source");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("source parameterisation"), std::string::npos) << r.output;
  const codec::RglBsdf again = codec::read_rgl_bsdf(dir / "again.bsdf");
  EXPECT_EQ(again.theta_i, src.theta_i);
  EXPECT_EQ(again.ndf, src.ndf);
  EXPECT_EQ(again.sigma, src.sigma);
  EXPECT_EQ(again.vndf, src.vndf);
  EXPECT_EQ(again.resolution, 12u);
  r = run_specula("export " + back + " -o " + q(dir / "rgb.bsdf") + " --rgb --parameterisation source");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("source parameterisation"), std::string::npos) << r.output;
  EXPECT_EQ(codec::read_rgl_bsdf(dir / "rgb.bsdf").vndf, src.vndf);
  r = run_specula("export " + back + " -o " + q(dir / "t.bsdf") + " --target-de00 0.5");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("4 theta_i x 12^2 samples, source parameterisation"), std::string::npos) << r.output;

  for (const std::string& args :
       {q(grid) + " --parameterisation source", back + " --parameterisation source --resolution 16"}) {
    r = run_specula("export " + args + " -o " + q(dir / "x.bsdf"));
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_NE(r.output.find("source parameterisation"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.bsdf"));
  }
}

TEST(BsdfCli, MalformedFilesGiveOneLineAndExitOne) {
  test::ScratchDir dir;
  const auto store_path = dir / "s.h5";
  auto r = run_specula("synth-brdf green-matte --wavelengths 400:700:100 -o " + q(store_path) + ":keep");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string before = test::read_bytes(store_path);
  test::write_file(dir / "magic.bsdf", std::string("tensor_filX\0\1\0\0\0\0\0", 18));
  test::write_file(dir / "short.bsdf", std::string("tensor_file\0\1\0\1\0\0\0\1\0a\1\0\12", 24));
  for (const char* name : {"magic.bsdf", "short.bsdf"}) {
    r = run_specula("import " + q(dir / name) + " -o " + q(store_path));
    EXPECT_EQ(r.status, 1) << name << ": " << r.output;
    EXPECT_NE(r.output.find(name), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    r = run_specula("render " + q(dir / name) + " -o " + q(dir / "x.png"));
    EXPECT_EQ(r.status, 1) << name << ": " << r.output;
  }
  EXPECT_EQ(test::read_bytes(store_path), before);
}
