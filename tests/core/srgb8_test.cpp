// encode_srgb8 against the IEC 61966-2-1 transfer function written out here.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "specula/core/colour.h"
#include "specula/core/error.h"

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
