// `specula import` of spectral libraries (ENVI .sli, USGS splib07a, ECOSTRESS) as collections, and the bbl of
// ENVI images honoured or kept with --keep-bad-bands.
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <fstream>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

void write_text(const std::filesystem::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary);
  out << s;
}

std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

// A 2-spectrum x 3-band little-endian float32 library; spectrum s band b = s + 0.25 * (b + 1).
void write_sli(const std::filesystem::path& dir, const std::string& extra = "") {
  write_text(dir / "lib.hdr",
             "ENVI\nsamples = 3\nlines = 2\nbands = 1\nheader offset = 0\nfile type = ENVI Spectral Library\n"
             "data type = 4\ninterleave = bsq\nbyte order = 0\nwavelength units = Nanometers\n"
             "wavelength = {500, 600, 700}\nspectra names = {Green paint, Red brick}\n" +
                 extra);
  std::string bytes;
  for (int s = 0; s < 2; ++s)
    for (int b = 0; b < 3; ++b) {
      const auto w = std::bit_cast<std::uint32_t>(float(s) + 0.25f * float(b + 1));
      for (int i = 0; i < 4; ++i) bytes += char((w >> (8 * i)) & 0xff);
    }
  write_text(dir / "lib.sli", bytes);
}

}  // namespace

TEST(ImportLibraryCli, EnviSliBecomesACollectionWithNames) {
  test::ScratchDir dir;
  write_sli(dir.path(), "bbl = {1, 0, 1}\n");
  const auto db = dir / "db.h5";
  auto r = run_specula("-q import " + quoted(dir / "lib.sli") + " -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  auto s = store::Store::open(db);
  auto c = s.read_collection("lib");
  EXPECT_EQ(c.names, (std::vector<std::string>{"Green paint", "Red brick"}));
  ASSERT_EQ(c.bands(), 2u);  // 600 nm is bad in bbl
  EXPECT_EQ(c.wavelengths[1], 700);
  EXPECT_EQ(c.values, (std::vector<float>{0.25f, 0.75f, 1.25f, 1.75f}));

  r = run_specula("-q import " + quoted(dir / "lib.hdr") + " --keep-bad-bands --name all -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  c = store::Store::open(db).read_collection("all");
  EXPECT_EQ(c.bands(), 3u);
  EXPECT_EQ(c.values[4], 1.5f);
}

TEST(ImportLibraryCli, EnviImageBblHonouredOrKept) {
  test::ScratchDir dir;
  write_text(dir / "img.hdr",
             "ENVI\nsamples = 1\nlines = 1\nbands = 3\nheader offset = 0\ndata type = 1\ninterleave = bip\n"
             "byte order = 0\nwavelength units = Nanometers\nwavelength = {450, 550, 650}\nbbl = {0, 1, 1}\n");
  write_text(dir / "img.raw", std::string{7, 8, 9});
  const auto db = dir / "db.h5";
  auto r = run_specula("-q import " + quoted(dir / "img.hdr") + " -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  auto cube = store::Store::open(db).read_image("img");
  ASSERT_EQ(cube.bands, 2u);
  EXPECT_EQ(cube.wavelengths[0], 550);
  EXPECT_EQ(cube.pixel(0, 0)[0], 8.0f);
  r = run_specula("-q import " + quoted(dir / "img.hdr") + " --keep-bad-bands --name kept -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  cube = store::Store::open(db).read_image("kept");
  ASSERT_EQ(cube.bands, 3u);
  EXPECT_EQ(cube.pixel(0, 0)[0], 7.0f);

  // All bands bad: one line that names the flag, not the parameter.
  write_text(dir / "bad.hdr",
             "ENVI\nsamples = 1\nlines = 1\nbands = 3\nheader offset = 0\ndata type = 1\ninterleave = bip\n"
             "byte order = 0\nwavelength units = Nanometers\nwavelength = {450, 550, 650}\nbbl = {0, 0, 0}\n");
  write_text(dir / "bad.raw", std::string{7, 8, 9});
  r = run_specula("-q import " + quoted(dir / "bad.hdr") + " -o " + quoted(db));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--keep-bad-bands"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("honour_bbl"), std::string::npos) << r.output;
}

TEST(ImportLibraryCli, UsgsAndEcostressDetectedByContent) {
  test::ScratchDir dir;
  write_text(dir / "splib07a_Wavelengths_BECK_Beckman_0.2-3.0_microns.txt",
             "splib07a Record=1: Wavelengths BECK Beckman 0.2-3.0 microns\n   0.40000\n   0.50000\n   0.60000\n");
  write_text(dir / "splib07a_Calcite_WS272_BECKa_AREF.txt",
             "splib07a Record=2: Calcite WS272 BECKa AREF\n   0.5\n   -1.23e34\n   0.75\n");
  const auto db = dir / "db.h5";
  auto r = run_specula("import " + quoted(dir / "splib07a_Calcite_WS272_BECKa_AREF.txt") + " " +
                       quoted(dir / "splib07a_Wavelengths_BECK_Beckman_0.2-3.0_microns.txt") + " -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("dropped 1 of 3 bands"), std::string::npos) << r.output;
  auto c = store::Store::open(db).read_collection("splib07a_Calcite_WS272_BECKa_AREF");
  EXPECT_EQ(c.names, (std::vector<std::string>{"Calcite WS272 BECKa AREF"}));
  ASSERT_EQ(c.bands(), 2u);
  EXPECT_NEAR(c.wavelengths[1], 600, 1e-9);
  EXPECT_EQ(c.values, (std::vector<float>{0.5f, 0.75f}));

  // ECOSTRESS, forced with --format too.
  const std::string header =
      "Name: Tap water\nType: Water\nClass: Tap\nSubclass: none\nParticle Size: Liquid\nSample No.: tapwater\n"
      "Owner: JPL\nWavelength Range: All\nOrigin: test\nCollection Date: N/A\nDescription: test\n"
      "Measurement: Hemispherical reflectance\nFirst Column: X\nSecond Column: Y\n"
      "X Units: Wavelength (micrometers)\nY Units: Reflectance (percent)\nFirst X Value: 0.7\nLast X Value: 0.4\n"
      "Number of X Values: 3\nAdditional Information: none\n\n";
  write_text(dir / "water.spectrum.txt", header + "0.7\t2.0\n0.5\t4.0\n0.4\t8.0\n");
  r = run_specula("-q import --format ecostress " + quoted(dir / "water.spectrum.txt") + " -o " + quoted(db));
  ASSERT_EQ(r.status, 0) << r.output;
  c = store::Store::open(db).read_collection("water");
  EXPECT_EQ(c.names, (std::vector<std::string>{"Tap water"}));
  EXPECT_NEAR(c.wavelengths[0], 400, 1e-9);
  EXPECT_EQ(c.values, (std::vector<float>{0.08f, 0.04f, 0.02f}));
  EXPECT_EQ(c.units, "reflectance");

  // A USGS spectrum without its wavelengths file: one line.
  r = run_specula("-q import " + quoted(dir / "splib07a_Calcite_WS272_BECKa_AREF.txt") + " --name x -o " + quoted(db));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("exactly one Wavelengths file"), std::string::npos) << r.output;
}
