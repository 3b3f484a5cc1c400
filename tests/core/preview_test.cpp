#include "specula/core/preview.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula {
namespace {

TEST(Preview, ParseExposure) {
  EXPECT_FALSE(parse_exposure("auto").has_value());
  EXPECT_EQ(parse_exposure("-1.5"), -1.5);
  for (const char* bad : {"65", "", "1x", "nan", "bright"}) {
    try {
      parse_exposure(bad);
      ADD_FAILURE() << bad;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("exposure '"), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find("--"), std::string::npos) << "a library names no flag: " << e.what();
    }
  }
  EXPECT_EQ(parse_tone("reinhard"), ToneMap::reinhard);
  EXPECT_THROW(parse_tone("filmic"), UsageError);
}

TEST(Preview, AutoExposureMapsThe99thPercentileOfValidPixelsToOne) {
  const std::size_t n = 201;
  RowMatrixX3f xyz = RowMatrixX3f::Zero(n, 3);
  std::vector<std::uint8_t> mask(n, 1);
  for (std::size_t i = 0; i < 200; ++i) xyz(Eigen::Index(i), 1) = float(i + 1);  // Y = 1..200
  xyz(200, 1) = 1e9f;
  mask[200] = 0;  // a masked outlier does not count
  // Sorted valid Y: 1..200; the quantile takes index floor(0.99 * 199) = 197, Y = 198.
  EXPECT_DOUBLE_EQ(auto_exposure_stops(xyz, mask, SpectrumKind::radiance), -std::log2(198.0));
  EXPECT_EQ(auto_exposure_stops(xyz, mask, SpectrumKind::reflectance), 0.0);
  EXPECT_EQ(auto_exposure_stops(RowMatrixX3f::Zero(4, 3), {}, SpectrumKind::radiance), 0.0);
}

TEST(Preview, WhitesAreWhiteAndMaskedPixelsHaveTheMaskColour) {
  const auto grid = WavelengthGrid::range(400, 700, 10);
  const Eigen::Index b = Eigen::Index(grid.size());
  // A perfect reflector under D65 at 0 EV, and equal-energy radiance at automatic exposure, are both display white.
  RowMatrixXf ones = RowMatrixXf::Ones(6, b);
  PreviewSettings s;
  s.illuminant = illuminant("D65", grid);
  s.exposure_stops = 0.0;
  const std::vector<std::uint8_t> mask{1, 1, 0, 1, 1, 1};
  const Picture r = render_preview(ones, 3, 2, grid, SpectrumKind::reflectance, mask, s);
  ASSERT_EQ(r.srgb8.size(), 18u);
  for (std::size_t p = 0; p < 6; ++p)
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(r.srgb8[3 * p + c], p == 2 ? kMaskColour[c] : 255) << p << " " << c;
  EXPECT_NEAR(r.linear[0], 1.0f, 1e-4f);

  s.exposure_stops.reset();
  const Picture e = render_preview(ones * 37.0f, 3, 2, grid, SpectrumKind::radiance, {}, s);
  for (std::size_t i = 0; i < e.linear.size(); ++i) EXPECT_NEAR(e.linear[i], 1.0f, 1e-4f) << i;
  EXPECT_THROW(render_preview(ones, 4, 2, grid, SpectrumKind::radiance, {}, s), UsageError);
}

TEST(Preview, RenderingWhiteMapsToDisplayWhite) {
  const Eigen::Vector3d white(0.9, 0.8, 0.4);
  // One D65 (core's, x = 0.31271, y = 0.32902) against the sRGB matrix's rounded 0.3127, 0.3290: within 2e-4.
  const Eigen::Vector3d rgb = rendering_to_linear_srgb(white) * white;
  EXPECT_NEAR(rgb[0], 1.0, 5e-4);
  EXPECT_NEAR(rgb[1], 1.0, 5e-4);
  EXPECT_NEAR(rgb[2], 1.0, 5e-4);
  // Scaling the white scales nothing in the result: it is mapped to luminance 1.
  EXPECT_LT((rendering_to_linear_srgb(3 * white) * (3 * white) - rgb).norm(), 1e-12);
  EXPECT_THROW(rendering_to_linear_srgb(Eigen::Vector3d::Zero()), UsageError);
}

TEST(Preview, HeatRampEnds) {
  EXPECT_EQ(heat(0), (Rgb8{0, 0, 0}));
  EXPECT_EQ(heat(1), (Rgb8{255, 255, 255}));
  EXPECT_EQ(heat(7), (Rgb8{255, 255, 255}));
  EXPECT_EQ(heat(std::nan("")), (Rgb8{0, 0, 0}));
  EXPECT_EQ(heat(0.2), (Rgb8{30, 30, 140}));
}

TEST(Preview, SideBySidePlacesPanelsWithWhiteGaps) {
  Picture a{2, 1, {1, 1, 1, 2, 2, 2}, {}}, b{1, 1, {9, 9, 9}, {}};
  const std::vector<Picture> panels{a, b};
  const Picture p = side_by_side(panels, 1);
  EXPECT_EQ(p.width, 4u);
  EXPECT_EQ(p.srgb8, (std::vector<std::uint8_t>{1, 1, 1, 2, 2, 2, 255, 255, 255, 9, 9, 9}));
  Picture tall{1, 2, std::vector<std::uint8_t>(6, 0), {}};
  const std::vector<Picture> mismatched{a, tall};
  EXPECT_THROW(side_by_side(mismatched, 0), UsageError);
}

}  // namespace
}  // namespace specula
