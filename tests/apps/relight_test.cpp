// `specula relight`: von Kries scaling is exact for neutral surfaces, so spectral (eq 4.9) and RGB (eq 4.10)
// relighting agree on greys and disagree on narrow-band colours.
#include <gtest/gtest.h>

#include <cmath>

#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

double mean_de(const std::string& output) {
  const auto at = output.find("\"mean_ciede2000\":");
  if (at == std::string::npos) return NAN;
  return std::stod(output.substr(at + 17));
}

store::Cube cube_of(std::vector<float> spectrum, const std::string& units) {
  store::Cube c;
  c.resize(3, 4, spectrum.size());
  for (std::size_t p = 0; p < 12; ++p)
    std::copy(spectrum.begin(), spectrum.end(), c.data.begin() + std::ptrdiff_t(p * 31));
  c.wavelengths = WavelengthGrid::range(420, 720, 10);
  c.units = units;
  return c;
}

}  // namespace

TEST(RelightCli, NeutralsAgreeAndNarrowBandColoursDiffer) {
  test::ScratchDir dir;
  auto path = dir / "db.h5";
  std::vector<float> grey(31, 0.4f), narrow(31, 0.02f);
  narrow[8] = narrow[9] = 0.9f;  // a saturated cyan-green: 500-510 nm
  {
    store::StoreWriter w(path, {});
    w.add_image("grey", cube_of(grey, "reflectance"));
    w.add_image("narrow", cube_of(narrow, "reflectance"));
    w.commit();
  }
  auto r = run_specula("relight '" + path.string() + "' grey --to A --json -o '" + (dir / "g.png").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LT(mean_de(r.output), 1e-3) << r.output;
  r = run_specula("relight '" + path.string() + "' narrow --to A --json -o '" + (dir / "n.png").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_GT(mean_de(r.output), 1.0) << r.output;
  auto png = store::read_png(dir / "n.png");
  EXPECT_EQ(png.width, 4u * 4 + 3 * 4);  // four panels with 4-pixel gaps
  EXPECT_EQ(png.height, 3u);
}

TEST(RelightCli, RadianceResultDoesNotDependOnTheDataScale) {
  test::ScratchDir dir;
  auto path = dir / "db.h5";
  std::vector<float> lo(31), hi(31);
  for (int b = 0; b < 31; ++b) {
    lo[std::size_t(b)] = 0.1f + 0.8f * float(b) / 30.0f;
    hi[std::size_t(b)] = lo[std::size_t(b)] * 64.0f;  // the same scene, 6 stops brighter units
  }
  {
    store::StoreWriter w(path, {});
    w.add_image("lo", cube_of(lo, "radiance"));
    w.add_image("hi", cube_of(hi, "radiance"));
    w.commit();
  }
  auto a =
      run_specula("relight '" + path.string() + "' lo --from D65 --to A --json -o '" + (dir / "a.png").string() + "'");
  auto b =
      run_specula("relight '" + path.string() + "' hi --from D65 --to A --json -o '" + (dir / "b.png").string() + "'");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  EXPECT_GT(mean_de(a.output), 0.01);
  EXPECT_NEAR(mean_de(a.output), mean_de(b.output), 1e-4);
  EXPECT_EQ(test::read_bytes(dir / "a.png"), test::read_bytes(dir / "b.png"));
}

TEST(RelightCli, BadExposureIsOneLineAndWritesNothing) {
  test::ScratchDir dir;
  auto path = dir / "db.h5";
  {
    store::StoreWriter w(path, {});
    w.add_image("grey", cube_of(std::vector<float>(31, 0.4f), "reflectance"));
    w.commit();
  }
  for (const char* bad : {"abc", "100", "nan"}) {
    auto r = run_specula("relight '" + path.string() + "' grey --exposure " + bad + " -o '" + (dir / "x.png").string() +
                         "'");
    EXPECT_EQ(r.status, 1) << bad << ": " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_NE(r.output.find("--exposure"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
  }
}
