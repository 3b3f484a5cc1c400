#include "specula/core/illuminant.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula {
namespace {

std::string usage_text(const std::string& spec, IlluminantFiles files = IlluminantFiles::allowed) {
  try {
    parse_illuminant(spec, WavelengthGrid::range(400, 700, 10), files);
  } catch (const UsageError& e) {
    return e.what();
  }
  return "no UsageError";
}

TEST(Illuminant, NamesAreTheCieTables) {
  const auto grid = WavelengthGrid::range(400, 700, 10);
  for (const char* name : {"D65", "D50", "A", "E"})
    EXPECT_EQ(parse_illuminant(name, grid), illuminant(name, grid)) << name;
  EXPECT_EQ(parse_illuminant("D75", grid), daylight(7500, grid));
  EXPECT_EQ(parse_illuminant("blackbody:3200", grid), blackbody(3200, grid));
}

TEST(Illuminant, CsvFileIsResampledToTheGrid) {
  const test::ScratchDir dir;
  const auto fine = WavelengthGrid::range(380, 780, 1);
  const Eigen::VectorXd bb = blackbody(5000, fine);
  {
    std::ofstream out(dir / "bb.csv");
    out << "wavelength_nm,value\r\n# a comment\n";
    for (std::size_t i = 0; i < fine.size(); ++i) out << fine[i] << (i % 2 ? ";" : ",") << bb[Eigen::Index(i)] << "\n";
  }
  const auto grid = WavelengthGrid::range(400, 700, 10);
  const Eigen::VectorXd got = parse_illuminant((dir / "bb.csv").string(), grid);
  const Eigen::VectorXd want = blackbody(5000, grid);
  ASSERT_EQ(got.size(), want.size());
  EXPECT_LT((got - want).cwiseAbs().maxCoeff(), 2e-3 * want.maxCoeff());
}

TEST(Illuminant, MalformedSpecsSayWhatIsAccepted) {
  EXPECT_NE(usage_text("D20").find("between D40 and D250"), std::string::npos) << usage_text("D20");
  EXPECT_NE(usage_text("blackbody:100").find("500-50000 K"), std::string::npos);
  EXPECT_NE(usage_text("tungsten").find("nor an existing SPD file"), std::string::npos);
  // A remote caller may not make specula read files: the form list, no file access.
  EXPECT_EQ(usage_text("/etc/passwd", IlluminantFiles::refused).find("SPD file"), std::string::npos);
  EXPECT_NE(usage_text("/etc/passwd", IlluminantFiles::refused).find("illuminant '/etc/passwd'"), std::string::npos);
}

TEST(Illuminant, BadFileNamesFileAndLine) {
  const test::ScratchDir dir;
  {
    std::ofstream out(dir / "bad.csv");
    out << "400,1\n500,2\n600,x\n";
  }
  const auto grid = WavelengthGrid::range(400, 600, 10);
  const std::string msg = test::input_error_text([&] { parse_illuminant((dir / "bad.csv").string(), grid); });
  EXPECT_NE(msg.find("bad.csv:3"), std::string::npos) << msg;
  {
    std::ofstream out(dir / "one.csv");
    out << "400,1\n";
  }
  EXPECT_NE(test::input_error_text([&] { parse_illuminant((dir / "one.csv").string(), grid); }).find("at least two"),
            std::string::npos);
}

}  // namespace
}  // namespace specula
