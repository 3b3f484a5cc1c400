// ENVI spectral libraries (.sli + .hdr) and the bad band list (bbl) of ENVI images.
#include <bit>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/envi.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::error_of;
using specula::test::write_file;

using test::ScratchDir;

// float32 samples, big endian when asked, as ENVI writes them.
std::string floats(const std::vector<float>& v, bool big_endian) {
  std::string out;
  for (float f : v) {
    const auto bits = std::bit_cast<std::uint32_t>(f);
    for (int i = 0; i < 4; ++i) out += static_cast<char>((bits >> (8 * (big_endian ? 3 - i : i))) & 0xff);
  }
  return out;
}

// Spectrum s, band b of the planted library: distinct, exactly representable values.
float lib_value(std::size_t s, std::size_t b) { return static_cast<float>(0.125 * (s + 1) + 0.0078125 * b); }

// A library header as ENVI writes it: 3 spectra (lines) x 5 bands (samples), wavelengths in micrometres,
// the wavelengths listed out of order (ENVI allows it) so the reader must sort them with the values.
std::string library_header(const std::string& extra = "", bool big_endian = true, std::size_t offset = 0) {
  return "ENVI\ndescription = {\n  Spectral Library written by a test}\nsamples = 5\nlines   = 3\nbands   = 1\n"
         "header offset = " +
         std::to_string(offset) +
         "\nfile type = ENVI Spectral Library\ndata type = 4\ninterleave = bsq\nsensor type = Unknown\n"
         "byte order = " +
         (big_endian ? "1" : "0") +
         "\nwavelength units = Micrometers\nreflectance scale factor = 1.000000\n"
         "wavelength = {\n 0.4000, 0.5000, 0.9000,\n 0.7000, 0.6000}\n"
         "spectra names = {\n Alunite GDS84 Na03, Kaolinite CM9,\n Dry Grass}\n" +
         extra;
}

const std::vector<double> kLibWl = {0.4, 0.5, 0.9, 0.7, 0.6};  // file order

std::string library_data(bool big_endian, std::size_t offset = 0) {
  std::vector<float> v;
  for (std::size_t s = 0; s < 3; ++s)
    for (std::size_t b = 0; b < 5; ++b) v.push_back(lib_value(s, b));
  return std::string(offset, '\0') + floats(v, big_endian);
}

TEST(SpectralLibrary, EnviSliReadsNamesSortedGridAndExactValues) {
  ScratchDir dir;
  for (bool big : {true, false}) {
    write_file(dir / "lib.sli", library_data(big, 16));
    write_file(dir / "lib.hdr", library_header("", big, 16));
    for (const auto& path : {dir / "lib.sli", dir / "lib.hdr"}) {
      const Collection c = read_envi_library(path);
      ASSERT_EQ(c.size(), 3u);
      EXPECT_EQ(c.names, (std::vector<std::string>{"Alunite GDS84 Na03", "Kaolinite CM9", "Dry Grass"}));
      ASSERT_EQ(c.bands(), 5u);
      // Ascending: 400 500 600 700 900 nm = file bands 0 1 4 3 2.
      const std::vector<std::size_t> file_band = {0, 1, 4, 3, 2};
      const std::vector<double> nm = {400, 500, 600, 700, 900};
      for (std::size_t k = 0; k < 5; ++k) EXPECT_NEAR(c.wavelengths[k], nm[k], 1e-9);
      for (std::size_t s = 0; s < 3; ++s)
        for (std::size_t k = 0; k < 5; ++k)
          EXPECT_EQ(c.values[s * 5 + k], lib_value(s, file_band[k])) << "spectrum " << s << " band " << k;
      EXPECT_EQ(c.provenance.importer, "envi-library");
    }
  }
  EXPECT_TRUE(is_envi_library(dir / "lib.sli"));
  EXPECT_TRUE(is_envi_library(dir / "lib.hdr"));
}

TEST(SpectralLibrary, EnviSliWithoutWavelengthsTakesTheFallback) {
  ScratchDir dir;
  std::string h = library_header();
  h.replace(h.find("wavelength = {"), h.find("spectra names") - h.find("wavelength = {"), "");
  write_file(dir / "lib.hdr", h);
  write_file(dir / "lib.sli", library_data(true));
  std::string m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("no wavelengths"), std::string::npos) << m;
  m = error_of([&] { read_envi_library(dir / "lib.sli", true, WavelengthGrid::parse("400:600:100")); });
  EXPECT_NE(m.find("5 bands (samples) but the `wavelengths` option gives 3"), std::string::npos) << m;
  const Collection c = read_envi_library(dir / "lib.sli", true, WavelengthGrid::parse("400:800:100"));
  ASSERT_EQ(c.bands(), 5u);
  EXPECT_EQ(c.wavelengths[4], 800);
  EXPECT_EQ(c.values[4], lib_value(0, 4));
}

TEST(SpectralLibrary, EnviSliBblDropsBadBandsUnlessKept) {
  ScratchDir dir;
  write_file(dir / "lib.sli", library_data(true));
  write_file(dir / "lib.hdr", library_header("bbl = {1, 0, 1, 1, 0}\n"));
  const Collection c = read_envi_library(dir / "lib.sli");
  // Bad: file bands 1 (500 nm) and 4 (600 nm). Kept ascending: 400 (0), 700 (3), 900 (2).
  ASSERT_EQ(c.bands(), 3u);
  EXPECT_NEAR(c.wavelengths[0], 400, 1e-9);
  EXPECT_NEAR(c.wavelengths[1], 700, 1e-9);
  EXPECT_NEAR(c.wavelengths[2], 900, 1e-9);
  for (std::size_t s = 0; s < 3; ++s) {
    EXPECT_EQ(c.values[s * 3 + 0], lib_value(s, 0));
    EXPECT_EQ(c.values[s * 3 + 1], lib_value(s, 3));
    EXPECT_EQ(c.values[s * 3 + 2], lib_value(s, 2));
  }
  const Collection all = read_envi_library(dir / "lib.sli", /*honour_bbl=*/false);
  EXPECT_EQ(all.bands(), 5u);
  EXPECT_EQ(all.values[2], lib_value(0, 4));  // 600 nm is third ascending
}

TEST(SpectralLibrary, EnviSliBadInputsAreOneLineNamingTheFile) {
  ScratchDir dir;
  write_file(dir / "lib.hdr", library_header());
  // Truncated: one spectrum short.
  write_file(dir / "lib.sli", library_data(true).substr(0, 40));
  std::string m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("lib.hdr"), std::string::npos) << m;
  EXPECT_NE(m.find("truncated"), std::string::npos) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  // Wrong count of names.
  write_file(dir / "lib.sli", library_data(true));
  std::string h = library_header();
  h.replace(h.find("Dry Grass"), 9, "Dry Grass, Extra");
  write_file(dir / "lib.hdr", h);
  m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("spectra names has 4 names but lines = 3"), std::string::npos) << m;
  EXPECT_NE(m.find("lib.hdr: line "), std::string::npos) << m;
  // Wrong count of wavelengths (one per sample).
  h = library_header();
  h.replace(h.find(" 0.7000, 0.6000}"), 16, " 0.7000}");
  write_file(dir / "lib.hdr", h);
  m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("wavelength has 4 values but samples = 5"), std::string::npos) << m;
  // A library read as an image, an image read as a library.
  write_file(dir / "lib.hdr", library_header());
  m = error_of([&] { read_envi(dir / "lib.sli"); });
  EXPECT_NE(m.find("read_envi_library"), std::string::npos) << m;
  h = library_header();
  h.replace(h.find("ENVI Spectral Library"), 21, "ENVI Standard");
  write_file(dir / "lib.hdr", h);
  m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("lib.hdr: line 15: wavelength has 5 values but bands = 1"), std::string::npos) << m;
  EXPECT_FALSE(is_envi_library(dir / "lib.sli"));
  // A well-formed image header is not a library.
  write_file(dir / "img.hdr", "ENVI\nsamples = 5\nlines = 3\nbands = 1\ndata type = 4\ninterleave = bsq\n");
  write_file(dir / "img.raw", library_data(true));
  m = error_of([&] { read_envi_library(dir / "img.raw"); });
  EXPECT_NE(m.find("img.hdr: file type = (absent) is not ENVI Spectral Library"), std::string::npos) << m;
  // Bad bbl entries.
  write_file(dir / "lib.hdr", library_header("bbl = {1, 2, 1, 1, 1}\n"));
  m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("bbl value 2 is 2"), std::string::npos) << m;
  write_file(dir / "lib.hdr", library_header("bbl = {0, 0, 0, 0, 0}\n"));
  m = error_of([&] { read_envi_library(dir / "lib.sli"); });
  EXPECT_NE(m.find("honour_bbl"), std::string::npos) << m;
  EXPECT_EQ(m.find("--"), std::string::npos) << m;
}

// A 1 x 2 image with 4 bands (bip float32 little endian), bands 2 and 4 marked bad.
TEST(EnviBbl, ImageBadBandsDroppedWithWavelengthsOrKept) {
  ScratchDir dir;
  std::vector<float> v;
  for (std::size_t x = 0; x < 2; ++x)
    for (std::size_t b = 0; b < 4; ++b) v.push_back(static_cast<float>(10 * x + b + 1));
  write_file(dir / "img.raw", floats(v, false));
  write_file(dir / "img.hdr",
             "ENVI\nsamples = 2\nlines = 1\nbands = 4\nheader offset = 0\nfile type = ENVI Standard\n"
             "data type = 4\ninterleave = bip\nbyte order = 0\nwavelength units = Nanometers\n"
             "wavelength = {450, 550, 650, 750}\nfwhm = {5, 6, 7, 8}\nbbl = {1.0, 0.0, 1.0, 0.0}\n");
  const Cube c = read_envi(dir / "img.hdr");
  ASSERT_EQ(c.bands, 2u);
  ASSERT_EQ(c.wavelengths.size(), 2u);
  EXPECT_EQ(c.wavelengths[0], 450);
  EXPECT_EQ(c.wavelengths[1], 650);
  EXPECT_EQ(c.fwhm, (std::vector<double>{5, 7}));
  EXPECT_EQ(c.pixel(0, 0)[0], 1.0f);
  EXPECT_EQ(c.pixel(0, 0)[1], 3.0f);
  EXPECT_EQ(c.pixel(0, 1)[0], 11.0f);
  EXPECT_EQ(c.pixel(0, 1)[1], 13.0f);

  const Cube all = read_envi(dir / "img.hdr", {}, /*honour_bbl=*/false);
  ASSERT_EQ(all.bands, 4u);
  EXPECT_EQ(all.wavelengths[3], 750);
  EXPECT_EQ(all.pixel(0, 1)[3], 14.0f);
  EXPECT_EQ(all.fwhm.size(), 4u);

  // bbl with the wrong count is one line naming the header line.
  std::ofstream(dir / "img.hdr", std::ios::app) << "bbl = {1, 1}\n";
  const std::string m = error_of([&] { read_envi(dir / "img.hdr"); });
  EXPECT_NE(m.find("bbl has 2 values but bands = 4"), std::string::npos) << m;
}

}  // namespace
}  // namespace specula::store
