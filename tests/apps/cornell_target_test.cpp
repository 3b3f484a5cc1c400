// The codec's target on measured data: a Cornell BRDF (../shared) imported and resampled from the command line,
// cut to 8 of its 31 bands to keep the test quick (still the measured values), encoded to the target and judged on
// the decoded grid by the separately written suite evaluation (tests/codec/suite_reference.h).
#include <gtest/gtest.h>

#include <string>

#include "codec/suite_reference.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_target.h"
#include "specula/codec/spectral_grid.h"
#include "test_support.h"

namespace specula {
namespace {

using test::run_specula;

// Every 4th band (400, 440, ..., 680 nm) of a grid file.
store::Grid every_fourth_band(const std::filesystem::path& file) {
  const store::Grid full = codec::read_grid_file(file);
  store::Grid cut;
  std::vector<double> nm;
  for (std::size_t b = 0; b < full.bands(); b += 4) {
    nm.push_back(full.wavelengths[b]);
    cut.brdf.insert(cut.brdf.end(), full.brdf.begin() + std::ptrdiff_t(b * brdf::kMerlCells),
                    full.brdf.begin() + std::ptrdiff_t((b + 1) * brdf::kMerlCells));
  }
  cut.wavelengths = WavelengthGrid(nm);
  cut.scale = full.scale;
  return cut;
}

class CornellTarget : public testing::TestWithParam<std::string> {};

TEST_P(CornellTarget, TheTargetIsMetAsAnIndependentSuiteRunMeasuresIt) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  const auto db = dir / "cornell.h5";
  const auto grid = dir / "mystique.spgrid";
  auto r = run_specula("import '" + (test::shared_dir() / "data/brdf/cornell/mystique.brdf").string() + "' -o '" +
                       db.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("resample '" + db.string() + "' mystique -o '" + grid.string() + "' --weights " + GetParam());
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Grid g = every_fourth_band(grid);
  ASSERT_EQ(g.bands(), 8u);
  const codec::LightingSuite suite(g.wavelengths, {.size = 24});
  const codec::SpcTarget target{.de00_mean = 0.5, .de00_p95 = 1.5, .condition_mean = 1.0, .max_trials = 6};
  codec::SpcTargetReport tr;
  // As many spectra as bands: mystique's spectra need 8 or more of 31 (docs/benchmarks.md), so a smaller basis
  // would meet an error floor before the transform's step is what is tested.
  const auto bytes = codec::encode_spc_to_target(g, codec::self_basis(g, g.bands()), {}, target, suite, tr);
  const store::Grid back = codec::decode_spc(bytes, "mystique");
  const test::ReferenceVerdict v = test::reference_verdict(g, back, suite);
  EXPECT_TRUE(tr.reached);
  EXPECT_TRUE(test::meets_target(v, target));
  // The encoder's own suite and the reference agree on what it coded, and it did not code losslessly.
  EXPECT_NEAR(v.mean, tr.de00_mean, 0.02);
  EXPECT_GT(v.mean, 0.1);
}

INSTANTIATE_TEST_SUITE_P(Weights, CornellTarget, testing::Values("shepard", "renka"));

}  // namespace
}  // namespace specula
