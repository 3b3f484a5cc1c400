// `specula resample --model` from the command line: every valid cell of the result has data, the confidence grid
// lies beside it, the fitted model is reported, and a bad model name or --model with --prior is one line leaving
// the output store alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "specula/acquire/prior.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula {
namespace {

using test::run_specula;

TEST(ModelCli, ResamplesEveryValidCellOnAFittedModelWithConfidenceBeside) {
  test::ScratchDir dir;
  const std::string db = (dir / "db.h5").string(), out = (dir / "out.h5").string();
  auto r =
      run_specula("synth-samples cyan-gloss --geometry random -n 30000 --wavelengths 400:700:100 -o '" + db + ":scan'");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("resample '" + db + "' scan --model beckmann --fresnel dielectric -k 4 -o '" + out + ":g' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "valid_cells"), double(acquire::valid_cells().size()));
  EXPECT_NE(r.output.find("\"distribution\":\"beckmann\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"eta\""), std::string::npos) << r.output;
  const store::Store s = store::Store::open(out);
  const store::Grid g = s.read_grid("g"), c = s.read_grid("g.confidence");
  EXPECT_EQ(c.units, "confidence");
  for (const std::uint32_t cell : acquire::valid_cells()) {
    ASSERT_GE(g.brdf[cell], 0.0f) << cell;
    ASSERT_GE(c.brdf[cell], 0.0f) << cell;
    ASSERT_LE(c.brdf[cell], 1.0f) << cell;
  }

  const std::string before = test::read_bytes(out);
  for (const std::string& bad :
       {std::string("--model phong"), std::string("--model ggx --lobes 3"), "--model ggx --prior '" + db + ":p'"}) {
    r = run_specula("resample '" + db + "' scan " + bad + " -o '" + out + ":h'");
    EXPECT_NE(r.status, 0) << bad;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_EQ(test::read_bytes(out), before) << bad;
  }
}

}  // namespace
}  // namespace specula
