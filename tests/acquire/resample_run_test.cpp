// A whole resample as one library call: the grid equals the one the separate steps (choice, then resampling)
// give, and its provenance and report name what was done.
#include "specula/acquire/resample_run.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "specula/acquire/store_samples.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// A store holding 20 000 random samples of two smooth bands, as "scan".
std::filesystem::path scan_store(const test::ScratchDir& dir) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  std::vector<double> angles;
  std::vector<float> values;
  for (int i = 0; i < 20000; ++i) {
    const double ti = t(rng), pi_ = p(rng), to = t(rng), po = p(rng);
    angles.insert(angles.end(), {ti, pi_, to, po});
    for (int q = 0; q < 2; ++q) values.push_back(float(1 + std::cos(ti + 0.2 * q) * std::cos(to)));
  }
  const auto path = dir / "s.h5";
  store::StoreWriter w(path, {});
  w.create_samples("scan", WavelengthGrid::parse("500:600:100"), "1/sr", {});
  w.append_samples("scan", angles, values);
  w.commit();
  return path;
}

constexpr double kGapDeg = 8.6;

TEST(ResampleRun, AutoKResamplesWithTheChoiceAsTheSeparateStepsDo) {
  test::ScratchDir dir;
  const auto path = scan_store(dir);
  const BandwidthOptions b{.ladder = {4, 8, 16}, .held_out = 300};
  const ResampleJob job{.store = path.string(),
                        .samples = "scan",
                        .local = {.weights = brdf::Weights::wendland, .max_gap = kGapDeg * pi / 180},
                        .k_auto = b};
  const ResampleOutcome r = run_resample(job);
  const store::Store s = store::Store::open(path);
  const BandwidthChoice c = choose_bandwidth(s, "scan", job.local, b);
  brdf::ResampleOptions chosen = job.local;
  chosen.k = c.k;
  std::vector<float> grid(2 * brdf::kMerlCells);
  brdf::resample_grid(StoreSamples(s, "scan"), chosen, grid);
  EXPECT_TRUE(r.grid.brdf == grid);
  EXPECT_FALSE(r.confidence);
  EXPECT_EQ(r.report["k"], c.k);
  EXPECT_EQ(r.report["k_auto"]["k"], c.k) << r.report.dump();
  EXPECT_EQ(r.grid.provenance.importer,
            "resample mapping=standard " + bandwidth_provenance(c, b) + " weights=wendland max_gap_deg=8.6");
  EXPECT_EQ(r.grid.provenance.source_file, path.string() + ":scan");
}

TEST(ResampleRun, AGivenKIsReportedAndNamedInTheProvenance) {
  test::ScratchDir dir;
  const auto path = scan_store(dir);
  const ResampleOutcome r = run_resample(
      {.store = path.string(), .samples = "scan", .local = {.k = 8, .power = 2, .max_gap = kGapDeg * pi / 180}});
  EXPECT_EQ(r.grid.provenance.importer, "resample mapping=standard k=8 weights=shepard power=2 max_gap_deg=8.6");
  std::size_t valid = 0;
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c) valid += r.grid.brdf[c] >= 0;
  EXPECT_GT(valid, 100000u);
  EXPECT_EQ(r.report["valid_cells"], valid);
  EXPECT_EQ(r.report["samples"], 20000);
  EXPECT_FALSE(r.report.contains("k_auto"));
  EXPECT_EQ(r.summary.rfind("resampled 20000 samples of scan onto " + std::to_string(valid), 0), 0u) << r.summary;
}

TEST(ResampleRun, RefusesBadOptionsAndMissingInput) {
  test::ScratchDir dir;
  const auto path = scan_store(dir);
  EXPECT_THROW(run_resample({.store = path.string(), .samples = "scan", .local = {.k = 0}}), UsageError);
  EXPECT_THROW(run_resample({.store = path.string(), .samples = "missing"}), InputError);
  EXPECT_THROW(run_resample({.store = path.string(), .samples = "scan", .method = PriorMethod{.prior = "no-store"}}),
               UsageError);
}

}  // namespace
}  // namespace specula::acquire
