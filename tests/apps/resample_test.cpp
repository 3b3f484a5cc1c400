// Cornell samples imported, resampled onto the grid and cross-validated from the command line; with a prior the
// kd-tree's k chosen by its holdout; bad input is one line and leaves the store alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "specula/store/store.h"
#include "test_support.h"

namespace specula {
namespace {

using test::run_specula;

TEST(ResampleCli, CornellSamplesResampleOntoTheGridAndCrossValidate) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  const auto db = dir / "cornell.h5";
  const auto data = test::shared_dir() / "data/brdf/cornell";
  auto r = run_specula("import '" + (data / "garnet_red.brdf").string() + "' '" + (data / "cayman.brdf").string() +
                       "' -o '" + db.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Store s = store::Store::open(db);
  EXPECT_EQ(s.samples_info("garnet_red").size, 1439u);
  r = run_specula("resample '" + db.string() + "' garnet_red -o '" + db.string() + ":garnet_red' -k 16 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"\"samples\":1439", "\"cells\":1458000", "\"valid_cells\":", "\"seconds\":"})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << ": " << r.output;
  const store::Grid g = store::Store::open(db).read_grid("garnet_red");
  std::size_t valid = 0;
  for (std::size_t c = 0; c < 1458000; ++c) valid += g.brdf[c] >= 0;
  EXPECT_GT(valid, 100000u);
  EXPECT_NE(r.output.find("\"valid_cells\":" + std::to_string(valid)), std::string::npos) << r.output;
  r = run_specula("eval-resample '" + db.string() + "' garnet_red --holdout 0.1 -k 1,16 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  // 3 mappings x (k = 1 nearest; k = 16 mean, Shepard, Renka, Wendland and LOESS), inside one object.
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '{'), 1 + 3 * 6) << r.output;
}

TEST(ResampleCli, SimulatedScanSamplesResampleIntoAStoreOrAGridFile) {
  test::ScratchDir dir;
  const auto db = dir / "scan.h5";
  auto q = [](const std::filesystem::path& p) { return "'" + p.string() + "'"; };
  auto r = run_specula(
      "synth-samples study-ward --sphere-px 40 --lights 50 --light-step 3 --wavelengths 500:600:50 "
      "--noise 0.01 -o " +
      q(db) + ":scan --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const double n = test::json_number(r.output, "samples");
  EXPECT_GT(n, 20000);
  EXPECT_EQ(store::Store::open(db).samples_info("scan").size, std::size_t(n));
  EXPECT_EQ(store::Store::open(db).samples_info("scan").bands, 3u);
  // -n thins evenly to exactly n.
  r = run_specula("synth-samples study-ward --sphere-px 40 --lights 50 -n 5000 -o " + q(db) + ":thin --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "samples"), 5000);
  r = run_specula("resample " + q(db) + " scan -o " + q(dir / "g.spgrid") + " -k 8 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"samples", "cells", "valid_cells", "seconds", "tree_seconds", "passes"})
    EXPECT_FALSE(std::isnan(test::json_number(r.output, key))) << key << ": " << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "g.spgrid"));
  r = run_specula("resample " + q(db) + " scan -o " + q(db) + ":g --mapping marschner -k 8 --weights mean");
  ASSERT_EQ(r.status, 0) << r.output;
  // The same name again without --replace is refused before any work, and the store is kept.
  const std::string before = test::read_bytes(db);
  r = run_specula("resample " + q(db) + " scan -o " + q(db) + ":g");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--replace"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_bytes(db), before);
  // An option of one method without that method names the option and the method it belongs to.
  for (const auto& [args, message] :
       {std::pair<std::string, std::string>{"--lambda 0.1", "--lambda: only with --prior"},
        {"--log-residual-passes 2", "--log-residual-passes: only with --prior"},
        {"--no-energy-bound", "--no-energy-bound: only with --prior"},
        {"--fresnel dielectric", "--fresnel: only with --model"},
        {"--max-gap 200", "max_gap = 200 degrees: give degrees in (0, 180]"}}) {
    const auto r = run_specula("resample '" + db.string() + "' ok -o '" + db.string() + ":g' " + args);
    EXPECT_NE(r.output.find(message), std::string::npos) << args << ": " << r.output;
  }
  r = run_specula("resample " + q(db) + " scan -o " + q(db) + ":g --replace --power 2");
  EXPECT_EQ(r.status, 0) << r.output;
  // -k auto: the leave-one-out choice in the JSON (every ladder row) and in the grid's provenance.
  r = run_specula("resample " + q(db) + " scan -o " + q(db) +
                  ":auto --weights wendland -k auto --k-held-out 500 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto k = std::size_t(test::json_number(r.output, "k"));
  EXPECT_NE(r.output.find("\"k_auto\":{"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"held_out\":500"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '{'), 2 + 11) << r.output;  // report, choice, 11 rows
  const std::string provenance = store::Store::open(db).read_grid("auto").provenance.importer;
  EXPECT_NE(provenance.find("k=" + std::to_string(k) + " k_auto=loo criterion=bands held_out=500"), std::string::npos)
      << provenance;
}

TEST(ResampleCli, TheStudyPrintsEveryMappingKAndWeighting) {
  test::ScratchDir dir;
  const auto r = run_specula(
      "resample-study --sphere-px 40 --lights 60 -k 1,4 --render-size 32 --no-suite --json "
      "--out '" +
      (dir / "study").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  // Two materials x 3 mappings x (k = 1; k = 4 mean and Shepard).
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '{'), 1 + 2 + 2 * 9) << r.output;
  EXPECT_GT(test::json_number(r.output, "grid_l1"), 0) << r.output;
  // Under the lighting suite, one row per mapping: a sparse scan (60 lights, a 40-pixel sphere) resampled onto the
  // whole grid is visibly off and leaves cells without data.
  const auto su = run_specula(
      "resample-study --material study-ward --sphere-px 40 --lights 60 -k 1 --suite-k 4 "
      "--render-size 32 --json");
  ASSERT_EQ(su.status, 0) << su.output;
  EXPECT_EQ(std::count(su.output.begin(), su.output.end(), '{'), 1 + 1 + 3 + 3) << su.output;
  EXPECT_GT(test::json_number(su.output, "de00_mean"), 0.1) << su.output;
  EXPECT_LT(test::json_number(su.output, "de00_mean"), 50) << su.output;
  EXPECT_GE(test::json_number(su.output, "de00_p95"), test::json_number(su.output, "de00_mean")) << su.output;
  EXPECT_GT(test::json_number(su.output, "hole_cells"), 0) << su.output;
  for (const char* f : {"study-ts-renders.png", "study-ward-renders.png", "study-ts-incidence.png"})
    EXPECT_TRUE(std::filesystem::exists(dir / "study" / f)) << f;
}

TEST(ResampleCli, BadInputIsOneLineAndLeavesTheStoreAlone) {
  test::ScratchDir dir;
  const auto db = dir / "s.h5";
  { std::ofstream(dir / "ok.brdf") << "2\n400 500\n0.5 0 0.5 3.1 1 2\n0.4 0 0.6 3.0 1 2\n0.3 0 0.2 1.0 3 4\n"; }
  { std::ofstream(dir / "cut.brdf") << "2\n400 500\n0.5 0 0.5 3.1 1\n"; }
  { std::ofstream(dir / "nan.brdf") << "2\n400 500\n0.5 0 0.5 3.1 1 nan\n"; }
  { std::ofstream(dir / "count.brdf") << "3\n400 500 600\n0.5 0 0.5 3.1 1 2 3\n0.5 0 0.5 3.1 1 2\n"; }
  ASSERT_EQ(run_specula("import '" + (dir / "ok.brdf").string() + "' -o '" + db.string() + "'").status, 0);
  const std::string before = test::read_bytes(db);
  for (const std::string& args :
       {"import '" + (dir / "cut.brdf").string() + "' -o '" + db.string() + "'",
        "import '" + (dir / "nan.brdf").string() + "' -o '" + db.string() + "'",
        "import '" + (dir / "count.brdf").string() + "' -o '" + db.string() + "'",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --weights median",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --power -1",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --weights renka --power 2",
        "resample '" + db.string() + "' ok -o '" + (dir / "g.txt").string() + "'",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":bad/name'",
        "eval-resample '" + db.string() + "' ok -k 0",
        "synth-samples velvet -o '" + db.string() + ":s'",
        "synth-samples study-ts --geometry random -o '" + db.string() + ":s'",
        "synth-samples study-ts --sphere-px 0 -o '" + db.string() + ":s'",
        "synth-samples study-ts -o '" + (dir / "s.txt").string() + "'",
        std::string("resample-study -k 0"),
        std::string("resample-study --material velvet"),
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --mapping polar",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k 0",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k many",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k holdout",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k auto --k-criterion mean",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k auto --k-held-out 0",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' -k 8 --k-held-out 100",
        "resample '" + db.string() + "' missing -o '" + db.string() + ":g'",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --max-gap 200",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --lambda 0.1",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --no-log-residuals",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --lobes 2",
        "resample '" + db.string() + "' ok -o '" + db.string() + ":g' --confidence-reach 0.5",
        "eval-resample '" + db.string() + "' ok --holdout 1.5"}) {
    const auto r = run_specula(args);
    EXPECT_EQ(r.status, 1) << args << ": " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << ": " << r.output;
  }
  EXPECT_EQ(test::read_bytes(db), before);
}

TEST(ResampleCli, WithAPriorTheKdTreesKChosenByTheHoldoutIsTheGivenKsGrid) {
  // -k holdout keeps one k of its ladder, reports every k's least error, and writes the grid that k given outright
  // writes, bit for bit; it needs --prior with the reach chosen, each refusal one line leaving the store alone.
  test::ScratchDir dir;
  const std::string db = (dir / "db.h5").string(), out = (dir / "out.h5").string(), wl = " --wavelengths 400:700:100";
  for (const char* m : {"blue-paint", "gold", "green-matte", "study-ts", "cyan-gloss"})
    ASSERT_EQ(run_specula(std::string("synth-brdf ") + m + wl + " -o '" + db + ":" + m + "'").status, 0) << m;
  ASSERT_EQ(run_specula("prior build '" + db + "' --exclude cyan-gloss --channels 3 -o '" + db + "' --name p").status,
            0);
  ASSERT_EQ(
      run_specula("synth-samples cyan-gloss --geometry random -n 40000 --noise 0.05" + wl + " -o '" + db + ":scan'")
          .status,
      0);
  auto r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -k holdout -o '" + out + ":h' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const double k = test::json_number(r.output, "k");
  EXPECT_TRUE(k == 8 || k == 16 || k == 32 || k == 64) << r.output;
  EXPECT_EQ(test::json_number(r.output.substr(r.output.find("\"confidence_reach_auto\"")), "k"), k) << r.output;
  EXPECT_NE(r.output.find("\"k_rows\":[{\"k\":8"), std::string::npos) << r.output;
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -k " + std::to_string(int(k)) + " -o '" + out +
                  ":g'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Store s = store::Store::open(out);
  EXPECT_EQ(s.read_grid("h").brdf, s.read_grid("g").brdf);
  EXPECT_NE(s.read_grid("h").provenance.importer.find("k_by_holdout=8,16,32,64"), std::string::npos);
  EXPECT_NE(s.read_grid("h").provenance.importer.find(" k=" + std::to_string(int(k)) + " weights="), std::string::npos);
  const std::string before = test::read_bytes(out);
  for (const std::string flags : {" -k holdout --confidence-reach 0.1", " -k holdout --prior-residuals"}) {
    r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -o '" + out + ":b'" + flags);
    EXPECT_EQ(r.status, 1) << flags;
    EXPECT_NE(r.output.find("-k holdout"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  EXPECT_EQ(test::read_bytes(out), before);
}

}  // namespace
}  // namespace specula
