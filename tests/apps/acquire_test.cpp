// `specula simulate-capture`, `specula acquire hdr` and `acquire run` end to end: statuses counted, saturation flagged
// and masked, broken captures and bad options refused with one line, the store left as it was, and the run's report
// under the lighting suite.
#include <gtest/gtest.h>

#include <filesystem>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using test::json_number;
using test::run_specula;

namespace {

const std::string kSmall =
    "--size 80x80 --sphere-px 50 --lights 2 --light-step 50 --bands 500,600 --exposures "
    "0.001,0.003,0.01,0.03,0.1,0.3,1 ";

TEST(AcquireCli, HdrCountsStatusesAndMasksSaturation) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string(), sat = (dir / "sat").string(), store = (dir / "s.h5").string();
  ASSERT_EQ(run_specula("simulate-capture " + kSmall + "--no-noise -o '" + cap + "'").status, 0);
  const auto r = run_specula("acquire hdr '" + cap + "' -o '" + store + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "lights"), 2);
  EXPECT_EQ(json_number(r.output, "pixels"), 2 * 80 * 80);
  EXPECT_EQ(json_number(r.output, "saturated"), 0);
  const double valid = json_number(r.output, "valid_pixels");
  EXPECT_GT(valid, 1000);
  const store::Store s = store::Store::open(store);
  EXPECT_EQ(s.images(), (std::vector<std::string>{"hdr-L000", "hdr-L001"}));
  EXPECT_EQ(s.image_info("hdr-L000").units, "DN/s");
  EXPECT_EQ(s.image_info("hdr-L000").valid_pixels + s.image_info("hdr-L001").valid_pixels, std::uint64_t(valid));

  // A light so bright that the shortest exposure saturates the sphere: flagged, and masked out.
  ASSERT_EQ(run_specula("simulate-capture " + kSmall + "--no-noise --brightness 1e9 -o '" + sat + "'").status, 0);
  const auto rs = run_specula("acquire hdr '" + sat + "' -o '" + (dir / "sat.h5").string() + "' --json");
  ASSERT_EQ(rs.status, 0) << rs.output;
  EXPECT_GT(json_number(rs.output, "saturated"), 1000);
  EXPECT_LT(json_number(rs.output, "valid_pixels"), valid / 4);
}

TEST(AcquireCli, BrokenCapturesAndBadOptionsGetOneLineAndLeaveTheStoreAlone) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string(), store = (dir / "s.h5").string();
  ASSERT_EQ(run_specula("simulate-capture " + kSmall + "-o '" + cap + "'").status, 0);
  ASSERT_EQ(run_specula("acquire hdr '" + cap + "' -o '" + store + "'").status, 0);
  const std::string before = test::read_bytes(store);
  std::filesystem::remove(dir / "cap" / "scene" / "L001" / "B600-30ms.png");
  const auto missing = run_specula("acquire hdr '" + cap + "' -o '" + store + "' --replace");
  EXPECT_EQ(missing.status, 1) << missing.output;
  EXPECT_NE(missing.output.find("scene/L001/B600-30ms.png"), std::string::npos) << missing.output;
  EXPECT_NE(missing.output.find("file is missing"), std::string::npos) << missing.output;
  EXPECT_EQ(test::read_bytes(store), before);

  const auto exists = run_specula("simulate-capture " + kSmall + "-o '" + cap + "'");
  EXPECT_EQ(exists.status, 1);
  EXPECT_NE(exists.output.find("exists"), std::string::npos) << exists.output;
  const auto size = run_specula("simulate-capture --size 80 -o '" + (dir / "x").string() + "'");
  EXPECT_EQ(size.status, 1);
  EXPECT_NE(size.output.find("WIDTHxHEIGHT"), std::string::npos) << size.output;
  const auto big = run_specula("simulate-capture --size 64x64 --sphere-px 200 -o '" + (dir / "y").string() + "'");
  EXPECT_EQ(big.status, 1);
  EXPECT_NE(big.output.find("does not fit"), std::string::npos) << big.output;
  const auto material = run_specula("simulate-capture --material unobtainium -o '" + (dir / "z").string() + "'");
  EXPECT_EQ(material.status, 1);
  EXPECT_NE(material.output.find("unobtainium"), std::string::npos) << material.output;
  for (const char* d : {"x", "y", "z"}) EXPECT_FALSE(std::filesystem::exists(dir / d)) << d;
  const auto none = run_specula("acquire hdr '" + (dir / "nothing").string() + "' -o '" + store + "'");
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.output.find("manifest.json"), std::string::npos) << none.output;
}

}  // namespace

// `acquire run` on a simulated capture reports the acquisition under the lighting suite: its figures are those of the
// separate commands a user would run (resample with the same k and gap, synth-brdf of the material, brdf-diff).
TEST(AcquireCli, RunReportsTheResampledCaptureUnderTheLightingSuite) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string(), store = (dir / "s.h5").string();
  ASSERT_EQ(run_specula("simulate-capture --size 64x64 --sphere-px 48 --lights 8 --light-step 20 --bands 420:720:50 "
                        "--exposures 0.001,0.01,0.1,1,8 -o '" +
                        cap + "'")
                .status,
            0);
  ASSERT_EQ(run_specula("acquire hdr '" + cap + "' -o '" + store + "'").status, 0);
  const auto r = run_specula("acquire run '" + cap + "' -o '" + store + ":rp' --grid-k 16 --grid-max-gap 15 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  ASSERT_NE(r.output.find("\"suite\":{\"suite\":{\"conditions\":38"), std::string::npos) << r.output;
  const auto grid = (dir / "grid.spgrid").string(), truth = (dir / "truth.spgrid").string();
  ASSERT_EQ(run_specula("resample '" + store + "' rp -k 16 --max-gap 15 -o '" + grid + "'").status, 0);
  ASSERT_EQ(run_specula("synth-brdf red-plastic --wavelengths 420:720:50 -o '" + truth + "'").status, 0);
  const auto d = run_specula("brdf-diff '" + truth + "' '" + grid + "' --json");
  ASSERT_EQ(d.status, 0) << d.output;
  for (const char* key : {"de00_mean", "de00_p95", "hole_cells", "rel_rms_cos"})
    EXPECT_NEAR(json_number(r.output, key), json_number(d.output, key), 1e-9 * (1 + json_number(d.output, key))) << key;
  EXPECT_GT(json_number(r.output, "de00_mean"), 0);
  const auto quiet = run_specula("acquire run '" + cap + "' -o '" + store + ":rp2' --no-suite --json");
  ASSERT_EQ(quiet.status, 0) << quiet.output;
  EXPECT_EQ(quiet.output.find("\"suite\""), std::string::npos);
}
