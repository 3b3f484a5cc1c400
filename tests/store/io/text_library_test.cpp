// USGS splib07a ASCII and ECOSTRESS text spectra read as collections, from fixtures in the public layouts.
#include <cmath>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/text_library.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::error_of;
using specula::test::write_file;

using test::ScratchDir;
using Paths = std::vector<std::filesystem::path>;

// splib07a layout: title line, then one right-aligned value per line.
std::string splib(const std::string& title, const std::vector<std::string>& values) {
  std::string s = title + "\n";
  for (const auto& v : values) s += "   " + v + "\n";
  return s;
}

const std::string kWlTitle = "splib07a Record=6: Wavelengths ASD 0.35-2.5 microns 2151 ch";

// Five channels, in micrometres as splib07a writes them.
void write_usgs_fixture(const ScratchDir& dir) {
  write_file(dir / "splib07a_Wavelengths_ASD_0.35-2.5_microns_2151_ch.txt",
             splib(kWlTitle, {"0.350000", "0.400000", "0.450000", "0.500000", "0.550000"}));
  write_file(dir / "splib07a_Alunite_GDS84_Na03_ASDFRa_AREF.txt",
             splib("splib07a Record=55: Alunite GDS84 Na03       ASDFRa AREF",
                   {"-1.23e34", "0.2500000", "0.5000000", "0.7500000", "0.1250000"}));
  write_file(dir / "splib07a_Kaolinite_CM9_ASDFRb_AREF.txt",
             splib("splib07a Record=3380: Kaolinite CM9          ASDFRb AREF",
                   {"0.0625000", "0.3750000", "0.6250000", "-1.2300000e+34", "0.8750000"}));
  write_file(dir / "splib07a_Empty_ASDFRa_AREF.txt",
             splib("splib07a Record=77: Empty sample ASDFRa AREF",
                   {"-1.23e34", "-1.23e34", "-1.23e34", "-1.23e34", "-1.23e34"}));
}

TEST(SpectralLibrary, UsgsSniffedAndMissingBandsAndEmptySpectraDropped) {
  ScratchDir dir;
  write_usgs_fixture(dir);
  const auto wl = dir / "splib07a_Wavelengths_ASD_0.35-2.5_microns_2151_ch.txt";
  EXPECT_EQ(sniff_text_library(wl), "usgs-wavelengths");
  EXPECT_EQ(sniff_text_library(dir / "splib07a_Kaolinite_CM9_ASDFRb_AREF.txt"), "usgs");
  const Paths spectra = {dir / "splib07a_Alunite_GDS84_Na03_ASDFRa_AREF.txt",
                         dir / "splib07a_Kaolinite_CM9_ASDFRb_AREF.txt", dir / "splib07a_Empty_ASDFRa_AREF.txt"};
  const TextLibrary lib = read_usgs_spectra(spectra, wl);
  const Collection& c = lib.collection;
  EXPECT_EQ(c.names, (std::vector<std::string>{"Alunite GDS84 Na03 ASDFRa AREF", "Kaolinite CM9 ASDFRb AREF"}));
  // Channel 1 (missing in Alunite) and channel 4 (missing in Kaolinite) are dropped with their wavelengths.
  ASSERT_EQ(c.bands(), 3u);
  EXPECT_NEAR(c.wavelengths[0], 400, 1e-9);
  EXPECT_NEAR(c.wavelengths[1], 450, 1e-9);
  EXPECT_NEAR(c.wavelengths[2], 550, 1e-9);
  EXPECT_EQ(c.values, (std::vector<float>{0.25f, 0.5f, 0.125f, 0.375f, 0.625f, 0.875f}));
  EXPECT_EQ(c.units, "reflectance");
  ASSERT_EQ(lib.notes.size(), 2u);
  EXPECT_NE(lib.notes[0].find("splib07a_Empty_ASDFRa_AREF.txt"), std::string::npos) << lib.notes[0];
  EXPECT_NE(lib.notes[1].find("dropped 2 of 5 bands"), std::string::npos) << lib.notes[1];
  for (float v : c.values) EXPECT_TRUE(std::isfinite(v));
}

TEST(SpectralLibrary, UsgsBadInputsNameFileAndLine) {
  ScratchDir dir;
  write_usgs_fixture(dir);
  const auto wl = dir / "splib07a_Wavelengths_ASD_0.35-2.5_microns_2151_ch.txt";
  // Truncated spectrum: fewer values than wavelengths.
  write_file(dir / "short.txt", splib("splib07a Record=9: Short ASDFRa AREF", {"0.1", "0.2", "0.3"}));
  std::string m = error_of([&] { read_usgs_spectra(Paths{dir / "short.txt"}, wl); });
  EXPECT_NE(m.find("short.txt: 3 values but"), std::string::npos) << m;
  EXPECT_NE(m.find("5 wavelengths"), std::string::npos) << m;
  // Non-numeric row.
  write_file(dir / "text.txt", splib("splib07a Record=9: Text ASDFRa AREF", {"0.1", "0.2", "abc", "0.4", "0.5"}));
  m = error_of([&] { read_usgs_spectra(Paths{dir / "text.txt"}, wl); });
  EXPECT_NE(m.find("text.txt: line 4: \"abc\" is not a number"), std::string::npos) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos);
  // A value no float32 holds (found by fuzzing: it became inf in the collection).
  write_file(dir / "huge.txt",
             splib("splib07a Record=9: Huge ASDFRa AREF", {"0.1", "0.2", "2300000e+34", "0.4", "0.5"}));
  m = error_of([&] { read_usgs_spectra(Paths{dir / "huge.txt"}, wl); });
  EXPECT_NE(m.find("huge.txt: line 4: value 2.3e+40 is beyond the float32 range of a store"), std::string::npos) << m;
  // Title only.
  write_file(dir / "title.txt", "splib07a Record=9: Title only\n");
  m = error_of([&] { read_usgs_spectra(Paths{dir / "title.txt"}, wl); });
  EXPECT_NE(m.find("title.txt: title line but no values"), std::string::npos) << m;
  // A spectrum given as the wavelengths file.
  m = error_of([&] { read_usgs_spectra(Paths{dir / "text.txt"}, dir / "splib07a_Kaolinite_CM9_ASDFRb_AREF.txt"); });
  EXPECT_NE(m.find("does not name Wavelengths"), std::string::npos) << m;
  // Only an all-missing spectrum.
  m = error_of([&] { read_usgs_spectra(Paths{dir / "splib07a_Empty_ASDFRa_AREF.txt"}, wl); });
  EXPECT_NE(m.find("no spectrum holds any valid value"), std::string::npos) << m;
}

// ECOSTRESS layout: "Key: value" header, blank line, tab-separated rows in descending wavelength.
std::string ecostress(const std::string& name, const std::vector<std::pair<std::string, std::string>>& rows,
                      const std::string& x_units = "Wavelength (micrometers)",
                      const std::string& y_units = "Reflectance (percent)", std::size_t declared = 0) {
  std::string s = "Name: " + name +
                  "\nType: Mineral\nClass: Silicate\nSubclass: Inosilicate\n"
                  "Particle Size:  125-500 um\nSample No.: InS-1A\nOwner: JHU\nWavelength Range: TIR\n"
                  "Origin: Synthetic test fixture\nCollection Date: N/A\n"
                  "Description: A test spectrum written in the ECOSTRESS layout.\n"
                  "Measurement: Directional (10 Degree) Hemispherical Reflectance\n"
                  "First Column: X\nSecond Column: Y\nX Units: " +
                  x_units + "\nY Units: " + y_units + "\nFirst X Value: " + rows.front().first +
                  "\nLast X Value: " + rows.back().first +
                  "\nNumber of X Values: " + std::to_string(declared ? declared : rows.size()) +
                  "\nAdditional Information: none\n\n";
  for (const auto& [x, y] : rows) s += x + "\t" + y + "\n";
  return s;
}

TEST(SpectralLibrary, EcostressSortedConvertedAndGridsMustAgree) {
  ScratchDir dir;
  write_file(dir / "a.spectrum.txt",
             ecostress("Acmite NaFe+3(SiO3)2", {{"0.8", "50.0"}, {"0.6", "25.0"}, {"0.5", "12.5"}, {"0.4", "6.25"}}));
  write_file(dir / "b.spectrum.txt",
             ecostress("Dry grass", {{"0.8", "80.0"}, {"0.6", "60.0"}, {"0.5", "40.0"}, {"0.4", "20.0"}}));
  EXPECT_EQ(sniff_text_library(dir / "a.spectrum.txt"), "ecostress");
  const TextLibrary lib = read_ecostress_spectra(Paths{dir / "a.spectrum.txt", dir / "b.spectrum.txt"});
  const Collection& c = lib.collection;
  EXPECT_EQ(c.names, (std::vector<std::string>{"Acmite NaFe+3(SiO3)2", "Dry grass"}));
  ASSERT_EQ(c.bands(), 4u);
  const std::vector<double> nm = {400, 500, 600, 800};  // non-uniform, kept exactly
  for (std::size_t k = 0; k < 4; ++k) EXPECT_NEAR(c.wavelengths[k], nm[k], 1e-9);
  EXPECT_EQ(c.values, (std::vector<float>{0.0625f, 0.125f, 0.25f, 0.5f, 0.2f, 0.4f, 0.6f, 0.8f}));
  EXPECT_EQ(c.units, "reflectance");
  EXPECT_EQ(c.provenance.importer, "ecostress (micrometers->nm, percent->fraction)");

  // A third file on another grid: one line naming it.
  write_file(dir / "c.spectrum.txt", ecostress("Other", {{"0.8", "1"}, {"0.7", "2"}, {"0.5", "3"}, {"0.4", "4"}}));
  const std::string m = error_of([&] {
    read_ecostress_spectra(Paths{dir / "a.spectrum.txt", dir / "b.spectrum.txt", dir / "c.spectrum.txt"});
  });
  EXPECT_NE(m.find("c.spectrum.txt: its wavelengths"), std::string::npos) << m;
  EXPECT_NE(m.find("differ from " + (dir / "a.spectrum.txt").string()), std::string::npos) << m;
  EXPECT_NE(m.find("band 3"), std::string::npos) << m;

  // A wrapped Description line that starts with a number stays in the header.
  std::string wrapped = ecostress("Wrapped", {{"0.8", "50.0"}, {"0.6", "25.0"}, {"0.5", "12.5"}, {"0.4", "6.25"}});
  wrapped.replace(wrapped.find("layout.\n") + 8, 0, "2 um grains were sieved out.\n");
  write_file(dir / "w.spectrum.txt", wrapped);
  const Collection w = read_ecostress_spectra(Paths{dir / "w.spectrum.txt", dir / "a.spectrum.txt"}).collection;
  EXPECT_EQ(w.names, (std::vector<std::string>{"Wrapped", "Acmite NaFe+3(SiO3)2"}));
  EXPECT_EQ(w.values[3], 0.5f);

  // Nanometres and plain fractions pass through unchanged.
  write_file(dir / "nm.txt", ecostress("Plain", {{"450", "0.5"}, {"650", "0.25"}}, "Wavelength (nanometers)",
                                       "Reflectance (fraction)"));
  const Collection p = read_ecostress_spectra(Paths{dir / "nm.txt"}).collection;
  EXPECT_EQ(p.wavelengths[0], 450);
  EXPECT_EQ(p.values, (std::vector<float>{0.5f, 0.25f}));
  EXPECT_EQ(p.provenance.importer, "ecostress");
}

TEST(SpectralLibrary, EcostressBadInputsNameFileAndLine) {
  ScratchDir dir;
  // Truncated: header says 4, file has 3 rows. Header line 19 is Number of X Values.
  write_file(dir / "t.txt", ecostress("T", {{"0.8", "1"}, {"0.6", "2"}, {"0.5", "3"}}, "Wavelength (micrometers)",
                                      "Reflectance (percent)", 4));
  std::string m = error_of([&] { read_ecostress_spectra(Paths{dir / "t.txt"}); });
  EXPECT_NE(m.find("t.txt: line 19: Number of X Values says 4 but the file has 3 data rows; the file is truncated"),
            std::string::npos)
      << m;
  // Non-numeric row: rows start at line 22.
  write_file(dir / "n.txt", ecostress("N", {{"0.8", "1"}, {"0.6", "x2"}}));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "n.txt"}); });
  EXPECT_NE(m.find("n.txt: line 23: \"0.6?x2\" is not a row of two numbers"), std::string::npos) << m;
  // A row count no size_t holds (found by fuzzing: converting it was undefined).
  write_file(dir / "count.txt",
             ecostress("N", {{"0.8", "1"}, {"0.6", "2"}}, "Wavelength (micrometers)", "Reflectance (percent)", 0));
  {
    std::string text;
    std::ifstream in(dir / "count.txt");
    for (std::string line; std::getline(in, line);)
      text += (line.starts_with("Number of X Values") ? "Number of X Values: 5e52" : line) + "\n";
    write_file(dir / "count.txt", text);
  }
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "count.txt"}); });
  EXPECT_NE(m.find("count.txt: line 19: Number of X Values = \"5e52\" is not a whole number from 1 to 2^32 - 1"),
            std::string::npos)
      << m;
  // Y Units holding carriage returns (found by fuzzing) stay out of the one-line message.
  write_file(dir / "a.txt", ecostress("A", {{"0.8", "1"}, {"0.6", "2"}}));
  write_file(dir / "cr.txt",
             ecostress("B", {{"0.8", "1"}, {"0.6", "2"}}, "Wavelength (micrometers)", "Reflecta\r\rnce (percent)"));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "a.txt", dir / "cr.txt"}); });
  EXPECT_NE(m.find("cr.txt: Y Units (reflecta??nce, percent) differ from"), std::string::npos) << m;
  EXPECT_EQ(m.find_first_of("\r\n"), std::string::npos) << m;
  // A value no float32 holds.
  write_file(dir / "huge.txt", ecostress("N", {{"0.8", "1"}, {"0.6", "1e39"}}));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "huge.txt"}); });
  EXPECT_NE(m.find("huge.txt: line 23: value 1e+39 is beyond the float32 range of a store"), std::string::npos) << m;
  // Three columns.
  write_file(dir / "three.txt", ecostress("N", {{"0.8", "1 2"}, {"0.6", "2"}}));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "three.txt"}); });
  EXPECT_NE(m.find("three.txt: line 22:"), std::string::npos) << m;
  // Wavenumbers are not read.
  write_file(dir / "w.txt", ecostress("W", {{"400", "1"}, {"500", "2"}}, "Wavenumber (cm-1)"));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "w.txt"}); });
  EXPECT_NE(m.find("w.txt: X Units = \"Wavenumber (cm-1)\" is not a wavelength"), std::string::npos) << m;
  // Repeated wavelength.
  write_file(dir / "d.txt", ecostress("D", {{"0.8", "1"}, {"0.8", "2"}}));
  m = error_of([&] { read_ecostress_spectra(Paths{dir / "d.txt"}); });
  EXPECT_NE(m.find("d.txt: line 23: wavelength 0.8 appears twice"), std::string::npos) << m;
}

}  // namespace
}  // namespace specula::store
