// encode_srgb8 (and band_preview, which encodes through it) against the IEC 61966-2-1 transfer function written out
// here.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/preview.h"

using namespace specula;

namespace {
int reference_code(double linear) {
  const double v = std::clamp(linear, 0.0, 1.0);
  const double e = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
  return int(std::lround(255 * e));
}
}  // namespace

TEST(EncodeSrgb8, ExposureClipAndBackground) {
  const std::vector<float> linear = {0.0f, 0.001f, 0.18f, 0.25f, 0.5f, 1.5f, 0.7f, 0.7f, 0.7f};
  const std::vector<std::uint8_t> covered = {1, 1, 0};
  std::vector<std::uint8_t> out(9);
  encode_srgb8(linear, covered, 1.0, out);  // gain 2
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(int(out[i]), reference_code(2.0 * linear[i])) << i;
  EXPECT_EQ(int(out[4]), 255);  // 0.5 x 2 is white
  for (std::size_t i = 6; i < 9; ++i) EXPECT_EQ(int(out[i]), 24);
  encode_srgb8(linear, covered, -2.0, out, 7);  // gain 1/4, another background
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(int(out[i]), reference_code(0.25 * linear[i])) << i;
  EXPECT_EQ(int(out[8]), 7);
}

TEST(EncodeSrgb8, SizesMustAgree) {
  const std::vector<float> linear(6, 0.5f);
  const std::vector<std::uint8_t> covered(3, 1);
  std::vector<std::uint8_t> out(6);
  EXPECT_THROW(encode_srgb8(linear, covered, 0.0, out), UsageError);
}

TEST(EncodeSrgb8, DoublePrecisionValuesAreEncodedWithoutRoundingToFloat) {
  // 0.5 + 1e-12 rounds to 0.5f; both encode alike, and every double matches the transfer function exactly.
  const std::vector<double> linear = {0.5 + 1e-12, 0.0031308, 0.2140, 0.9, 2.0, -1.0};
  const std::vector<std::uint8_t> covered = {1, 1};
  std::vector<std::uint8_t> out(6);
  encode_srgb8(std::span<const double>(linear), covered, 0.0, out);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(int(out[i]), reference_code(linear[i])) << i;
}

TEST(BandPreview, OneBandOverItsValidNinetyNinthPercentileWithMaskedPixelsMarked) {
  // 3 pixels of 2 bands; band 1 holds 0.1, 0.2 and (masked) 100: the masked value is left out of the scale.
  const std::vector<float> data = {9, 0.1f, 9, 0.2f, 9, 100.0f};
  const std::vector<std::uint8_t> mask = {1, 1, 0};
  std::vector<float> valid = {0.1f, 0.2f};
  const double top = quantile(valid, 0.99);
  const std::vector<std::uint8_t> rgb = band_preview(data, 2, 1, mask);
  ASSERT_EQ(rgb.size(), 9u);
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_EQ(int(rgb[c]), reference_code(double(0.1f) / top)) << c;
    EXPECT_EQ(int(rgb[3 + c]), reference_code(double(0.2f) / top)) << c;
    EXPECT_EQ(rgb[6 + c], kMaskColour[c]);
  }
  EXPECT_THROW(band_preview(data, 2, 2, mask), UsageError);
}
