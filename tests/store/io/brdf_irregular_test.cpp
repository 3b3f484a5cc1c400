#include "specula/store/io/brdf_irregular.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::store {
namespace {

void write(const std::filesystem::path& p, const std::string& text) { std::ofstream(p) << text; }

TEST(BrdfIrregular, ReadsTheCornellLayout) {
  test::ScratchDir dir;
  write(dir / "a.brdf",
        "# num wls\n3\n\n# wls\n400 500\n600\n# samples\n0.5 0 0.25 3.14159 0.1 0.2 0.3\n"
        "\n0.1 0.2 0.3 0.4 1 2 3 # trailing comment\n");
  const IrregularBrdf b = read_brdf_irregular(dir / "a.brdf");
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b.wavelengths.size(), 3u);
  EXPECT_EQ(b.wavelengths[2], 600);
  EXPECT_EQ(b.angles, (std::vector<double>{0.5, 0, 0.25, 3.14159, 0.1, 0.2, 0.3, 0.4}));
  EXPECT_EQ(b.values, (std::vector<float>{0.1f, 0.2f, 0.3f, 1, 2, 3}));
}

TEST(BrdfIrregular, TheRealCornellFileMatchesItsFirstLineReadByHand) {
  SPECULA_REQUIRE_SHARED();
  const IrregularBrdf b = read_brdf_irregular(test::shared_dir() / "data/brdf/cornell/acryl_blue.brdf");
  EXPECT_EQ(b.size(), 1439u);
  EXPECT_EQ(b.wavelengths.size(), 31u);
  EXPECT_EQ(b.wavelengths[0], 400);
  // "0.872665 0.000000 0.573513 0.000000 0.014369 0.018226 ..." and the last value 0.000008.
  EXPECT_DOUBLE_EQ(b.angles[0], 0.872665);
  EXPECT_DOUBLE_EQ(b.angles[2], 0.573513);
  EXPECT_FLOAT_EQ(b.values[0], 0.014369f);
  EXPECT_FLOAT_EQ(b.values[1], 0.018226f);
  EXPECT_FLOAT_EQ(b.values[30], 0.000008f);
}

// Independently: every Cornell file read line by line with a string stream; the lines of 35 numbers are the
// samples, and the reader must give each of them, in order.
TEST(BrdfIrregular, EveryCornellFileMatchesALineByLineReading) {
  SPECULA_REQUIRE_SHARED();
  for (const char* name : {"acryl_blue", "cayman", "garnet_red", "krylon_blue", "mystique"}) {
    const auto path = test::shared_dir() / "data/brdf/cornell" / (std::string(name) + ".brdf");
    std::ifstream in(path);
    std::vector<std::vector<double>> rows;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream ss(line);
      std::vector<double> row;
      for (double v; ss >> v;) row.push_back(v);
      if (row.size() == 35) rows.push_back(row);
    }
    const IrregularBrdf b = read_brdf_irregular(path);
    ASSERT_EQ(b.size(), rows.size()) << name;
    ASSERT_EQ(b.wavelengths.size(), 31u);
    EXPECT_EQ(b.wavelengths[30], 700);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (std::size_t a = 0; a < 4; ++a) ASSERT_EQ(b.angles[4 * i + a], rows[i][a]) << name << " sample " << i;
      for (std::size_t k = 0; k < 31; ++k)
        ASSERT_EQ(b.values[31 * i + k], float(rows[i][4 + k])) << name << " sample " << i;
    }
  }
}

TEST(BrdfIrregular, BadFilesNameTheLineAndTheRule) {
  test::ScratchDir dir;
  const std::pair<const char*, const char*> cases[] = {
      {"2\n400 500\n0.1 0 0.2 0 1\n", "has 5 numbers; expected 6"},
      {"2\n400 500\n0.1 0 0.2 0 1 2\n0.1 0 0.2 0 1 2 3\n0.1 0 0.2 0 1 2\n", "line 4: sample 2 has 7 numbers"},
      {"2\n400 500\n0.1 0 0.2 0 1\n2 0.1 0 0.2 0 1 2\n", "line 3: sample 1 has 5 numbers"},
      {"2\n400 500\n0.1 0 0.2 0 1 x\n", "'x'"},
      {"2\n400 500\n0.1 0 0.2 0 1 nan\n", "'nan'"},
      {"2\n400 500\n2.0 0 0.2 0 1 1\n", "outside [0, pi/2]"},
      {"2\n400 500\n0.1 0 0.2 0 1 -1\n", "negative"},
      {"2\n400\n", "ends within"},
      {"2\n500 400\n0.1 0 0.2 0 1 1\n", "increasing"},
      {"0\n", "wavelengths"},
      {"2\n400 500\n", "no samples"},
  };
  int i = 0;
  for (const auto& [text, expect] : cases) {
    const auto p = dir / ("bad" + std::to_string(i++) + ".brdf");
    write(p, text);
    const std::string what = test::input_error_text([&] { read_brdf_irregular(p); });
    EXPECT_NE(what.find(expect), std::string::npos) << text << " -> " << what;
    EXPECT_NE(what.find(p.filename().string()), std::string::npos) << what;
  }
  EXPECT_THROW(read_brdf_irregular(dir / "missing.brdf"), InputError);
}

}  // namespace
}  // namespace specula::store
