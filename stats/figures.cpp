#include "specula/stats/figures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "specula/core/error.h"

namespace specula::stats {
namespace {

// A horizontal colour bar of the error ramp from 0 to max_value at (x, y), labelled under its ends.
void error_bar(Canvas& c, std::size_t x, std::size_t y, std::size_t w, double max_value, std::size_t s) {
  colour_bar(c, x, y, w, heat, "L2 error", "0", number_label(max_value), s);
}

std::size_t error_bar_min_width(double max_value, std::size_t s) {
  return bar_min_width("L2 error", "0", number_label(max_value), s);
}

}  // namespace

std::vector<std::uint8_t> error_rgb(std::span<const float> error, std::span<const std::uint8_t> mask,
                                    double max_value) {
  std::vector<std::uint8_t> out(3 * error.size());
  for (std::size_t i = 0; i < error.size(); ++i) {
    const Rgb8 c = !mask.empty() && !mask[i] ? kMaskColour : heat(max_value > 0 ? error[i] / max_value : 0.0);
    std::copy(c.begin(), c.end(), out.begin() + std::ptrdiff_t(3 * i));
  }
  return out;
}

Canvas error_figure(std::size_t width, std::size_t height, std::span<const float> error,
                    std::span<const std::uint8_t> mask, double max_value) {
  const std::size_t s = font_scale(width), pad = 4 * s;
  const std::size_t inner = std::max(width, error_bar_min_width(max_value, s));
  Canvas c(inner + 2 * pad, pad + height + pad + bar_height(s) + pad);
  c.blit(pad + (inner - width) / 2, pad, width, height, error_rgb(error, mask, max_value));
  error_bar(c, pad, pad + height + pad, inner, max_value, s);
  return c;
}

Canvas projection_panel(std::size_t width, std::size_t height, std::span<const std::uint8_t> original,
                        std::span<const std::uint8_t> mask, std::span<const PanelColumn> columns) {
  if (columns.empty()) throw UsageError("projection_panel: no reconstructions to show");
  const std::size_t w = width, h = height, n = columns.size();
  const std::size_t s = font_scale(w), pad = 4 * s, line = 7 * s + 3 * s;
  double shared = 0;
  for (const PanelColumn& r : columns) shared = std::max(shared, r.max_error);
  std::vector<std::string> rms_labels;
  std::size_t col = std::max(w, text_width("original", s));
  for (const PanelColumn& r : columns) {
    rms_labels.push_back("rms " + number_label(r.rms));
    col = std::max({col, text_width(rms_labels.back(), s), text_width(fmt::format("k={}", r.k), s)});
  }
  const std::size_t bar_w_min = error_bar_min_width(shared, s);
  if (n * col + (n - 1) * pad < bar_w_min) col = (bar_w_min - (n - 1) * pad + n - 1) / n;
  const std::size_t top = pad + line, bottom = top + h + pad;
  const std::size_t bar_y = bottom + h + s + line + pad;
  Canvas c(pad + (n + 1) * col + n * pad + pad, bar_y + bar_height(s) + pad);
  auto column_x = [&](std::size_t i) { return pad + i * (col + pad); };
  auto centred = [&](std::size_t i, std::size_t text) { return column_x(i) + (col - text) / 2; };
  c.text(centred(0, text_width("original", s)), pad, "original", s);
  c.blit(centred(0, w), top, w, h, original);
  for (std::size_t i = 0; i < n; ++i) {
    const std::string label = fmt::format("k={}", columns[i].k);
    c.text(centred(i + 1, text_width(label, s)), pad, label, s);
    c.blit(centred(i + 1, w), top, w, h, columns[i].preview);
    c.blit(centred(i + 1, w), bottom, w, h, error_rgb(columns[i].error, mask, shared));
    c.text(centred(i + 1, text_width(rms_labels[i], s)), bottom + h + 2 * s, rms_labels[i], s);
  }
  error_bar(c, column_x(1), bar_y, n * col + (n - 1) * pad, shared, s);
  return c;
}

Canvas coefficient_figure(std::size_t height, std::size_t width, std::size_t k, std::span<const float> coefficients,
                          std::span<const std::uint8_t> mask, bool nmf) {
  const std::size_t h = height, w = width;
  const std::span<const float> c = coefficients;
  const std::size_t sc = font_scale(w), pad = 4 * sc, gap = 12 * sc, line = 10 * sc;
  const std::size_t columns = std::min<std::size_t>(k, 4), rows = (k + columns - 1) / columns;
  std::vector<double> range(k, 0.0);
  std::size_t panel_w = w;
  for (std::size_t j = 0; j < k; ++j) {
    std::vector<float> v;
    for (std::size_t p = 0; p < h * w; ++p)
      if (mask[p]) v.push_back(nmf ? c[p * k + j] : std::abs(c[p * k + j]));
    range[j] = quantile(v, 0.99);
    const std::string hi = number_label(range[j]), lo = nmf ? "0" : number_label(-range[j]);
    panel_w = std::max(panel_w, bar_min_width("", lo, hi, sc));
  }
  const std::size_t cell_h = line + h + pad + bar_height(sc);
  Canvas canvas(2 * pad + columns * panel_w + (columns - 1) * gap, pad + rows * (cell_h + pad));
  for (std::size_t j = 0; j < k; ++j) {
    const std::size_t x0 = pad + (j % columns) * (panel_w + gap), y0 = pad + (j / columns) * (cell_h + pad);
    const std::string label = fmt::format("c{}", j + 1);
    canvas.text(x0 + (panel_w - text_width(label, sc)) / 2, y0, label, sc);
    std::vector<std::uint8_t> picture(3 * h * w);
    for (std::size_t p = 0; p < h * w; ++p) {
      const double r = range[j] > 0 ? range[j] : 1.0;
      const Rgb8 col = !mask[p] ? kMaskColour : nmf ? heat(c[p * k + j] / r) : diverging(0.5 + 0.5 * c[p * k + j] / r);
      std::copy(col.begin(), col.end(), picture.begin() + std::ptrdiff_t(3 * p));
    }
    canvas.blit(x0 + (panel_w - w) / 2, y0 + line, w, h, picture);
    const std::string hi = number_label(range[j]), lo = nmf ? "0" : number_label(-range[j]);
    colour_bar(canvas, x0, y0 + line + h + pad, panel_w, nmf ? std::function<Rgb8(double)>(heat) : diverging, "", lo,
               hi, sc);
  }
  return canvas;
}

}  // namespace specula::stats
