// specula nmf and specula project --basis NMF through the command line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::read_bytes;
using specula::test::run_specula;

namespace {

struct Fixture {
  test::ScratchDir dir;
  std::filesystem::path db = dir / "db.h5";
  Fixture() {
    const auto r = run_specula("synth-db -o '" + db.string() + "' --images 2 --size 40x50 --quiet");
    EXPECT_EQ(r.status, 0) << r.output;
  }
  std::string quoted() const { return "'" + db.string() + "'"; }
};

std::size_t lines(const std::string& s) { return std::size_t(std::count(s.begin(), s.end(), '\n')); }

}  // namespace

TEST(NmfCli, JsonReportsTheFitAndTheBasisProjectsTheImageWithTheSameError) {
  Fixture f;
  auto r = run_specula("nmf " + f.quoted() + " -k 4 --images synth0 --max-epochs 30 --restarts 2 --json --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"\"k\":4", "\"n\":", "\"rel_error\":", "\"epochs\":", "\"seconds\":", "\"restarts\":[",
                          "\"basis\":\"nmf4\"", "\"svd_bound\":", "\"mean_angle_deg\":", "\"negatives\":"})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
  const double rel = test::json_number(r.output, "rel_error"), bound = test::json_number(r.output, "svd_bound");
  EXPECT_GT(rel, 0);
  EXPECT_GE(rel, bound);
  EXPECT_LT(rel, 0.2);
  EXPECT_FALSE(std::filesystem::exists(f.db.string() + ".nmf-nmf4.checkpoint"));  // removed once saved

  const store::Store s = store::Store::open(f.db);
  const store::Basis b = s.read_basis("nmf4");
  EXPECT_EQ(b.method, "nmf");
  EXPECT_EQ(b.k(), 4u);
  EXPECT_GE(b.components.minCoeff(), 0.0);
  EXPECT_EQ(b.n, std::uint64_t(test::json_number(r.output, "n")));
  const auto info = run_specula("info " + f.quoted() + " nmf4 --json");
  ASSERT_EQ(info.status, 0) << info.output;
  EXPECT_NE(info.output.find("\"method\":\"nmf\""), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("rel_error="), std::string::npos) << info.output;

  // The certified error is ||X - C*S|| / ||X|| with C* the exact NNLS coefficients: project recomputes C* pixel
  // by pixel, so its RMS over the same spectra must give the same error.
  const auto out = f.dir / "proj";
  auto p = run_specula("project " + f.quoted() + " --basis nmf4 --image synth0 --json -o '" + out.string() + "'");
  ASSERT_EQ(p.status, 0) << p.output;
  EXPECT_TRUE(std::filesystem::exists(out / "error-k4.png"));
  EXPECT_TRUE(std::filesystem::exists(out / "preview-k4.png"));
  EXPECT_TRUE(std::filesystem::exists(out / "reconstruction-k4.exr"));
  const double rms = test::json_number(p.output, "rms");
  const store::Cube cube = s.read_image("synth0");
  double xx = 0;
  std::size_t valid = 0;
  for (std::size_t px = 0; px < cube.height * cube.width; ++px) {
    if (!cube.mask.empty() && !cube.mask[px]) continue;
    ++valid;
    for (std::size_t k = 0; k < cube.bands; ++k) {
      const double v = std::max(0.0f, cube.data[px * cube.bands + k]);
      xx += v * v;
    }
  }
  const double from_project = rms * std::sqrt(double(valid) * double(cube.bands) / xx);
  EXPECT_NEAR(from_project, rel, 1e-5 * rel);
}

TEST(NmfCli, BadOptionsAndAnExistingBasisAreOneLineErrorsThatLeaveTheStoreAlone) {
  Fixture f;
  auto r = run_specula("nmf " + f.quoted() + " -k 3 --max-epochs 2 --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string before = read_bytes(f.db);
  for (const std::string& args :
       {std::string(" -k 3 --max-epochs 2"), std::string(" -k 40"), std::string(" -k 3 --init svd"),
        std::string(" -k 3 --negatives abs"), std::string(" -k 3 --resume --name fresh"),
        std::string(" -k 3 --images 'nomatch*' --name x")}) {
    r = run_specula("nmf " + f.quoted() + args + " --quiet");
    EXPECT_NE(r.status, 0) << args;
    EXPECT_EQ(lines(r.output), 1u) << args << ": " << r.output;
  }
  r = run_specula("nmf " + f.quoted() + " -k 3 --max-epochs 2 --quiet");
  EXPECT_NE(r.output.find("already exists"), std::string::npos) << r.output;
  r = run_specula("nmf " + f.quoted() + " -k 3 --resume --name fresh --quiet");
  EXPECT_NE(r.output.find("no checkpoint to resume from"), std::string::npos) << r.output;
  EXPECT_EQ(read_bytes(f.db), before);
}

TEST(NmfCli, InterruptedRunKeepsItsCheckpointAndResumes) {
  Fixture f;
  // SIGINT after the first epochs: the epoch loop stops at the next boundary and leaves the checkpoint.
  const std::string ckpt = (f.dir / "run.ckpt").string();
  const std::string cmd = "nmf " + f.quoted() + " -k 3 --tol 0 --max-epochs 100000 --checkpoint '" + ckpt + "' --quiet";
  auto r = run_specula(cmd + " 2>&1 & pid=$!; sleep 1.5; kill -INT $pid; wait $pid; echo status=$?");
  EXPECT_NE(r.output.find("status=130"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--resume"), std::string::npos) << r.output;
  ASSERT_TRUE(std::filesystem::exists(ckpt));
  EXPECT_TRUE(store::Store::open(f.db).bases().empty());  // nothing half-saved
  // Resumed with a loose tolerance it stops after its next epoch, saves the basis and removes the checkpoint.
  r = run_specula("nmf " + f.quoted() + " -k 3 --tol 0.5 --max-epochs 100000 --checkpoint '" + ckpt +
                  "' --resume --json --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"resumed\":true"), std::string::npos) << r.output;
  EXPECT_GE(test::json_number(r.output, "epochs"), 2.0);  // the epochs before the interruption count
  EXPECT_FALSE(std::filesystem::exists(ckpt));
  EXPECT_EQ(store::Store::open(f.db).bases().size(), 1u);
}

TEST(NmfCli, PlotBasisDrawsSeveralBasesAsOnePanelWithTheirCsv) {
  Fixture f;
  for (const char* k : {"2", "3"}) {
    const auto r = run_specula("nmf " + f.quoted() + " -k " + k + " --max-epochs 3 --quiet");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const auto out = f.dir / "fig";
  const auto r = run_specula("plot-basis " + f.quoted() + " nmf2 nmf3 -o '" + out.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Basis b = store::Store::open(f.db).read_basis("nmf3");
  std::ifstream csv(out / "nmf3-components.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header, "wavelength_nm,c1,c2,c3");
  for (std::size_t w = 0; std::getline(csv, line); ++w) {
    std::stringstream ss(line);
    std::string cell;
    std::getline(ss, cell, ',');
    EXPECT_DOUBLE_EQ(std::stod(cell), b.wavelengths[w]);
    for (Eigen::Index c = 0; c < 3; ++c) {
      std::getline(ss, cell, ',');
      EXPECT_NEAR(std::stod(cell), b.components(c, Eigen::Index(w)), 1e-12);
    }
  }
  EXPECT_TRUE(std::filesystem::exists(out / "nmf2-components.csv"));
  if (r.output.find("gnuplot not found") == std::string::npos) {
    EXPECT_TRUE(std::filesystem::exists(out / "panel.png"));
  }
}
