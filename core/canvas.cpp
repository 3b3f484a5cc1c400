#include "specula/core/canvas.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace specula {
namespace {

// Each row is 5 bits, the leftmost pixel in bit 4.
struct Glyph {
  char c;
  std::array<std::uint8_t, 7> rows;
};
constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}}, {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}},
    {'+', {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00}}, {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}},
    {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}}, {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F}},
    {'c', {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E}}, {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E}},
    {'f', {0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08}}, {'g', {0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
    {'i', {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E}}, {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12}},
    {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}}, {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11}},
    {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11}}, {'o', {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E}},
    {'p', {0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10}}, {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10}},
    {'s', {0x00, 0x00, 0x0F, 0x10, 0x0E, 0x01, 0x1E}}, {'t', {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06}},
    {'x', {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11}},
};

}  // namespace

void Canvas::put(std::size_t x, std::size_t y, Rgb8 c) {
  if (x < width && y < height) std::copy(c.begin(), c.end(), rgb.begin() + std::ptrdiff_t(3 * (y * width + x)));
}

void Canvas::fill(std::size_t x0, std::size_t y0, std::size_t w, std::size_t h, Rgb8 c) {
  for (std::size_t y = y0; y < y0 + h; ++y)
    for (std::size_t x = x0; x < x0 + w; ++x) put(x, y, c);
}

void Canvas::blit(std::size_t x0, std::size_t y0, std::size_t w, std::size_t h, std::span<const std::uint8_t> src) {
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x) {
      const std::uint8_t* p = src.data() + 3 * (y * w + x);
      put(x0 + x, y0 + y, {p[0], p[1], p[2]});
    }
}

void Canvas::text(std::size_t x0, std::size_t y0, std::string_view s, std::size_t scale) {
  for (char ch : s) {
    const auto* g = std::find_if(std::begin(kFont), std::end(kFont), [ch](const Glyph& f) { return f.c == ch; });
    if (g != std::end(kFont))
      for (std::size_t r = 0; r < 7; ++r)
        for (std::size_t col = 0; col < 5; ++col)
          if (g->rows[r] & (0x10 >> col)) fill(x0 + col * scale, y0 + r * scale, scale, scale, kInk);
    x0 += 6 * scale;
  }
}

std::size_t text_width(std::string_view s, std::size_t scale) { return s.empty() ? 0 : (6 * s.size() - 1) * scale; }

std::string number_label(double v) { return v == 0 ? std::string("0") : fmt::format("{:.3g}", v); }

std::size_t font_scale(std::size_t w) { return std::clamp<std::size_t>(w / 250 + 1, 1, 4); }

std::size_t bar_min_width(std::string_view title, std::string_view lo, std::string_view hi, std::size_t s) {
  return text_width(title, s) + 2 * std::max(text_width(lo, s), text_width(hi, s)) + 12 * s;
}

std::size_t bar_height(std::size_t s) { return 6 * s + 2 + 2 * s + 7 * s; }

void colour_bar(Canvas& c, std::size_t x, std::size_t y, std::size_t w, const std::function<Rgb8(double)>& ramp,
                std::string_view title, std::string_view lo, std::string_view hi, std::size_t s) {
  c.fill(x, y, w, 6 * s + 2, kInk);
  for (std::size_t i = 0; i + 2 < w; ++i)
    c.fill(x + 1 + i, y + 1, 1, 6 * s, ramp(double(i) / double(std::max<std::size_t>(1, w - 3))));
  const std::size_t ty = y + 6 * s + 2 + 2 * s;
  c.text(x, ty, lo, s);
  c.text(x + (w - std::min(w, text_width(title, s))) / 2, ty, title, s);
  c.text(x + w - std::min(w, text_width(hi, s)), ty, hi, s);
}

Rgb8 diverging(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const auto mix = [](double a, double b, double u) { return std::uint8_t(std::lround(a + (b - a) * u)); };
  if (t < 0.5) {
    const double u = t / 0.5;
    return {mix(33, 255, u), mix(102, 255, u), mix(172, 255, u)};
  }
  const double u = (t - 0.5) / 0.5;
  return {mix(255, 178, u), mix(255, 24, u), mix(255, 43, u)};
}

}  // namespace specula
