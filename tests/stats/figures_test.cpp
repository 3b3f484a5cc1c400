// The figure-7.4 panel and the error maps, checked by what they must show rather than by their layout: every picture
// appears whole and once, errors share one scale, masked pixels keep the mask colour.
#include <gtest/gtest.h>

#include <vector>

#include "specula/core/error.h"
#include "specula/stats/figures.h"

using namespace specula;

namespace {

std::size_t count(const Canvas& c, Rgb8 colour) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < c.width * c.height; ++i)
    n += c.rgb[3 * i] == colour[0] && c.rgb[3 * i + 1] == colour[1] && c.rgb[3 * i + 2] == colour[2];
  return n;
}

std::vector<std::uint8_t> flat(std::size_t pixels, Rgb8 colour) {
  std::vector<std::uint8_t> v(3 * pixels);
  for (std::size_t i = 0; i < pixels; ++i) std::copy(colour.begin(), colour.end(), v.begin() + std::ptrdiff_t(3 * i));
  return v;
}

}  // namespace

TEST(Figures, ErrorRgbMasksAndScales) {
  const std::vector<float> err = {0.0f, 1.0f, 2.0f, 2.0f};
  const std::vector<std::uint8_t> mask = {1, 1, 1, 0};
  const std::vector<std::uint8_t> rgb = stats::error_rgb(err, mask, 2.0);
  const Rgb8 want[] = {heat(0.0), heat(0.5), heat(1.0), kMaskColour};
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(rgb[3 * i + c], want[i][c]) << i << " " << c;
  const std::vector<std::uint8_t> none = stats::error_rgb(err, {}, 0.0);  // no mask, no error scale: all heat(0)
  for (std::size_t i = 0; i < none.size(); ++i) EXPECT_EQ(none[i], heat(0.0)[i % 3]);
}

TEST(Figures, PanelShowsEveryPictureOnceAndTheErrorsOnOneScale) {
  const std::size_t w = 12, h = 9, n = w * h;
  const Rgb8 original{1, 2, 3}, first{11, 0, 0}, second{12, 0, 0};
  const std::vector<std::uint8_t> o = flat(n, original), p1 = flat(n, first), p2 = flat(n, second);
  const std::vector<float> e1(n, 4.0f), e2(n, 2.0f);  // the second's errors are half the first's
  const stats::PanelColumn columns[] = {{1, 0.5, 4.0, e1, p1}, {3, 0.25, 2.0, e2, p2}};
  const Canvas c = stats::projection_panel(w, h, o, {}, columns);
  EXPECT_EQ(count(c, original), n);
  EXPECT_EQ(count(c, first), n);
  EXPECT_EQ(count(c, second), n);
  EXPECT_GE(count(c, heat(1.0)), n);  // the first error map at the top of the shared scale
  EXPECT_GE(count(c, heat(0.5)), n);  // the second at half of it, not rescaled to its own maximum
  EXPECT_GT(count(c, Rgb8{255, 255, 255}), c.width * c.height / 4);  // a white page
  EXPECT_THROW(stats::projection_panel(w, h, o, {}, {}), UsageError);
}

TEST(Figures, ErrorFigureKeepsMaskedPixels) {
  const std::size_t w = 8, h = 5;
  std::vector<float> err(w * h, 1.0f);
  std::vector<std::uint8_t> mask(w * h, 1);
  mask[3] = mask[17] = 0;
  const Canvas c = stats::error_figure(w, h, err, mask, 1.0);
  EXPECT_EQ(count(c, kMaskColour), 2u);
  EXPECT_GE(count(c, heat(1.0)), w * h - 2);
}
