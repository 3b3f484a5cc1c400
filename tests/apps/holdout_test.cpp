// `simulate-capture --holdout-targets` and `acquire run` on its chart: the held-out patches recovered from the captured
// images and reported per patch (the ColorChecker of ../shared when present), bad tables refused with one line naming
// the file and nothing written, and the held-out patches refused in a version-2 manifest.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "test_support.h"

using namespace specula;
using test::json_number;
using test::run_specula;

namespace {

const std::string kRig = "--size 80x80 --sphere-px 50 --lights 3 --light-step 30 --bands 420:720:20 --no-noise ";

// Patches in the shared data's layout: a wavelength column, then one quoted column per patch.
std::string patches_csv(double first_nm, double negative_at = 0) {
  std::string csv = "wavelength_nm,\"grey 5\",\"blue bump\",\"red edge\"\n";
  for (double l = first_nm; l <= 780; l += 5)
    csv += fmt::format("{},{},{:.4f},{:.4f}\n", l, l == negative_at ? -0.2 : 0.2,
                       0.05 + 0.4 * std::exp(-0.5 * std::pow((l - 460) / 30, 2)),
                       0.05 + 0.7 / (1 + std::exp(-(l - 600) / 15)));
  return csv;
}

}  // namespace

TEST(HoldoutCli, PatchesRecoveredFromTheCaptureAndReported) {
  test::ScratchDir dir;
  test::write_file(dir / "patches.csv", patches_csv(380));
  const auto cap = (dir / "cap").string(), out = (dir / "s.h5").string();
  auto r = run_specula("simulate-capture " + kRig + "--holdout-targets '" + (dir / "patches.csv").string() + "' -o '" +
                       cap + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "holdout_patches"), 3);
  r = run_specula("acquire calibrate '" + cap + "' -o '" + out + ":cal' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"name\":\"blue bump\""), std::string::npos) << r.output;
  // 16 delta-model bands of Gaussian passbands: the LCTF's own error on smooth patches, a few hundredths at most.
  EXPECT_LT(json_number(r.output, "rms_max"), 0.03) << r.output;
  EXPECT_GT(json_number(r.output, "rms_mean"), 0) << r.output;
  r = run_specula("acquire calibrate '" + cap + "' -o '" + out + ":text'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("held-out patches (never used by calibration)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("red edge"), std::string::npos) << r.output;

  // Held-out patches need format 3: a version-2 manifest that lists them is refused with one line.
  const auto manifest = std::filesystem::path(cap) / "manifest.json";
  std::string text = test::read_bytes(manifest);
  const auto at = text.find("\"version\": 3");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 12, "\"version\": 2");
  test::write_file(manifest, text);
  r = run_specula("acquire calibrate '" + cap + "' -o '" + out + ":v2'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("\"holdout_patches\" needs capture format version 3"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

TEST(HoldoutCli, BadTablesAreRefusedWithOneLineAndNothingWritten) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string();
  auto refused = [&](const std::string& file, const std::string& csv, const std::string& expect) {
    test::write_file(dir / file, csv);
    const auto r =
        run_specula("simulate-capture " + kRig + "--holdout-targets '" + (dir / file).string() + "' -o '" + cap + "'");
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.output.find(file + expect), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(std::filesystem::exists(cap));
    EXPECT_FALSE(std::filesystem::exists(cap + ".partial"));
  };
  refused("neg.csv", patches_csv(380, 500), ": patch 'grey 5' has a negative reflectance at 500 nm");
  refused("short.csv", patches_csv(450), ": tabulated on 450-780 nm, which does not cover the bands 420-720 nm");
  refused("text.csv", "wavelength_nm,a\n400,0.2\n500,grey\n", ":3:2: 'grey' is not a number");
}

TEST(HoldoutCli, ColorCheckerThroughTheLctf) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  const auto cc = test::shared_dir() / "data" / "reflectance" / "colorchecker24_ohta1997_reflectance.csv";
  const auto cap = (dir / "cap").string();
  auto r = run_specula("simulate-capture " + kRig + "--holdout-targets '" + cc.string() + "' -o '" + cap + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "holdout_patches"), 24);
  r = run_specula("acquire calibrate '" + cap + "' -o '" + (dir / "s.h5").string() + ":cal' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"name\":\"neutral 3.5 (1.05 D)\""), std::string::npos) << r.output;
  EXPECT_LT(json_number(r.output, "rms_mean"), 0.02) << r.output;
}
