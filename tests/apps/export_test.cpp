// `specula export`: previews against closed-form sRGB values, and file round trips through the CLI.
#include <gtest/gtest.h>

#include <fstream>

#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

std::filesystem::path store_with(const test::ScratchDir& dir, const std::string& name, store::Cube c) {
  auto path = dir / "db.h5";
  store::StoreWriter w(path, {});
  w.add_image(name, c);
  w.commit();
  return path;
}

store::Cube flat(std::size_t h, std::size_t w, float value, const std::string& units) {
  store::Cube c;
  c.resize(h, w, 31);
  std::fill(c.data.begin(), c.data.end(), value);
  c.wavelengths = WavelengthGrid::range(420, 720, 10);
  c.units = units;
  return c;
}

}  // namespace

TEST(ExportCli, WhiteAndMidGreyReflectanceGiveTheirSrgbCodes) {
  test::ScratchDir dir;
  store::Cube c = flat(4, 6, 1.0f, "reflectance");
  for (std::size_t p = 12; p < 24; ++p) std::fill_n(c.data.begin() + std::ptrdiff_t(p * 31), 31, 0.18f);
  auto path = store_with(dir, "chart", c);
  auto r = run_specula("export '" + path.string() + "' chart -o '" + (dir / "c.png").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  auto png = store::read_png(dir / "c.png");
  ASSERT_EQ(png.width, 6u);
  ASSERT_EQ(png.channels, 3u);
  // A perfect reflector under D65 is sRGB white; 18 % grey encodes to 118 (IEC 61966-2-1).
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(png.samples[std::size_t(k)], 255);
    EXPECT_NEAR(png.samples[3 * 12 + std::size_t(k)], 118, 1);
  }
}

TEST(ExportCli, EnviAndExrRoundTripThroughTheCli) {
  test::ScratchDir dir;
  store::Cube c = flat(5, 7, 0.0f, "radiance");
  for (std::size_t i = 0; i < c.data.size(); ++i) c.data[i] = float(i % 997) * 0.25f;
  auto path = store_with(dir, "scene", c);
  for (const char* file : {"s.raw", "s.exr"}) {
    auto out = dir / file;
    auto r = run_specula("-q export '" + path.string() + "' scene -o '" + out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.output;
    auto in = std::string(file) == "s.raw" ? dir / "s.hdr" : out;
    r = run_specula("-q import '" + in.string() + "' -o '" + (dir / "back.h5").string() + "' --replace --name back");
    ASSERT_EQ(r.status, 0) << r.output;
    auto back = store::Store::open(dir / "back.h5").read_image("back");
    EXPECT_EQ(back.data, c.data) << file;
    EXPECT_TRUE(back.wavelengths.approx_equal(c.wavelengths, 1e-9)) << file;
    EXPECT_EQ(back.units, "radiance") << file;
  }
}

TEST(ExportCli, UnknownObjectAndExtensionAreExplained) {
  test::ScratchDir dir;
  auto path = store_with(dir, "scene", flat(2, 2, 0.5f, "reflectance"));
  auto r = run_specula("export '" + path.string() + "' nope -o '" + (dir / "x.png").string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("no image 'nope' (images: scene)"), std::string::npos) << r.output;
  r = run_specula("export '" + path.string() + "' scene -o '" + (dir / "x.tiff").string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--format"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
}

TEST(ExportCli, SpdFileIlluminantEqualsTheBuiltInOne) {
  test::ScratchDir dir;
  store::Cube c = flat(3, 3, 0.0f, "reflectance");
  for (std::size_t i = 0; i < c.data.size(); ++i) c.data[i] = 0.05f + 0.9f * float(i % 31) / 30.0f;
  auto path = store_with(dir, "scene", c);
  {
    std::ofstream spd(dir / "flat.csv");
    spd << "wavelength_nm,power\n";
    for (int nm = 380; nm <= 780; nm += 20) spd << nm << "," << 3.5 << "\n";  // any constant is equal energy
  }
  auto a = run_specula("-q export '" + path.string() + "' scene -o '" + (dir / "a.png").string() + "' --illuminant E");
  auto b = run_specula("-q export '" + path.string() + "' scene -o '" + (dir / "b.png").string() + "' --illuminant '" +
                       (dir / "flat.csv").string() + "'");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  EXPECT_EQ(test::read_bytes(dir / "a.png"), test::read_bytes(dir / "b.png"));
  auto d = run_specula("-q export '" + path.string() + "' scene -o '" + (dir / "d.png").string() + "' --illuminant A");
  ASSERT_EQ(d.status, 0);
  EXPECT_NE(test::read_bytes(dir / "a.png"), test::read_bytes(dir / "d.png"));
  {
    std::ofstream bad(dir / "bad.csv");
    bad << "wavelength_nm,power\n400,1\n500,nan\n";
  }
  auto e = run_specula("-q export '" + path.string() + "' scene -o '" + (dir / "e.png").string() + "' --illuminant '" +
                       (dir / "bad.csv").string() + "'");
  EXPECT_EQ(e.status, 1);
  EXPECT_NE(e.output.find("bad.csv:3"), std::string::npos) << e.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "e.png"));
}
