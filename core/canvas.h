#pragma once
// Small RGB8 pictures with labels for the figures specula draws (the CLI writes them, the viewer and Python could
// show them): a white canvas, a 5x7 bitmap font and horizontal colour bars.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "specula/core/preview.h"

namespace specula {

inline constexpr Rgb8 kInk{40, 40, 40};

/// An RGB8 picture on a white background; text is drawn with a 5x7 font at `scale` pixels per font pixel.
struct Canvas {
  std::size_t width, height;
  std::vector<std::uint8_t> rgb;
  Canvas(std::size_t w, std::size_t h) : width(w), height(h), rgb(3 * w * h, 255) {}

  /// Sets pixel (x, y); outside the canvas does nothing.
  void put(std::size_t x, std::size_t y, Rgb8 c);
  /// Fills the w x h rectangle at (x0, y0).
  void fill(std::size_t x0, std::size_t y0, std::size_t w, std::size_t h, Rgb8 c);
  /// Copies a w x h RGB8 picture to (x0, y0).
  void blit(std::size_t x0, std::size_t y0, std::size_t w, std::size_t h, std::span<const std::uint8_t> src);
  /// Draws s with its top-left corner at (x0, y0); characters without a glyph leave a blank.
  void text(std::size_t x0, std::size_t y0, std::string_view s, std::size_t scale);
};

/// Width in pixels of s drawn at `scale`.
std::size_t text_width(std::string_view s, std::size_t scale);
/// A short label for a value: "0", or three significant digits.
std::string number_label(double v);
/// Font pixel size for pictures of width w: 1 below 250 pixels, growing to 4 for large images.
std::size_t font_scale(std::size_t w);
/// The narrowest colour bar that fits `title` and its end labels lo and hi under it.
std::size_t bar_min_width(std::string_view title, std::string_view lo, std::string_view hi, std::size_t s);
/// Height of a colour bar with its labels.
std::size_t bar_height(std::size_t s);
/// A horizontal bar of ramp(t), t from 0 at the left to 1 at the right, at (x, y), w wide, with lo, title and hi
/// written under its left end, middle and right end.
void colour_bar(Canvas& c, std::size_t x, std::size_t y, std::size_t w, const std::function<Rgb8(double)>& ramp,
                std::string_view title, std::string_view lo, std::string_view hi, std::size_t s);
/// A diverging ramp for signed values: blue at 0, white at 0.5, red at 1 (clamped).
Rgb8 diverging(double t);

}  // namespace specula
