#pragma once
// The figures of projections and coefficient maps (reference figure 7.4, its error maps, the coefficient images),
// drawn on a core Canvas: the CLI writes them as PNG, the viewer and Python can show the same pixels.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "specula/core/canvas.h"

namespace specula::stats {

/// One reconstruction of figure 7.4: its k, RMS and largest per-pixel error, the per-pixel L2 errors over bands and
/// its sRGB8 picture (3 bytes a pixel), both of the original's size.
struct PanelColumn {
  std::size_t k = 0;
  double rms = 0, max_error = 0;
  std::span<const float> error;
  std::span<const std::uint8_t> preview;
};

/// Per-pixel errors as RGB8 on the heat ramp from 0 to max_value (all 0 when max_value is 0); pixels the mask
/// rejects (one byte a pixel, 0 = masked; empty: none) in kMaskColour.
std::vector<std::uint8_t> error_rgb(std::span<const float> error, std::span<const std::uint8_t> mask, double max_value);

/// A width x height error map (error_rgb) above its colour bar "L2 error" from 0 to max_value.
Canvas error_figure(std::size_t width, std::size_t height, std::span<const float> error,
                    std::span<const std::uint8_t> mask, double max_value);

/// Figure 7.4: the original (sRGB8, width x height) and each reconstruction under "k=K" on top, their error maps on
/// one shared scale (the largest max_error) above "rms R" below, and the shared colour bar. UsageError without
/// columns.
Canvas projection_panel(std::size_t width, std::size_t height, std::span<const std::uint8_t> original,
                        std::span<const std::uint8_t> mask, std::span<const PanelColumn> columns);

/// A coefficient map's k images (height x width x k, pixel-major) side by side, at most four to a row, each under
/// "cJ" above its own colour bar: NMF coefficients on the heat ramp from 0 to their 99th percentile, PCA ones
/// blue-white-red around 0 to +-the 99th percentile of |c|; pixels the mask rejects in kMaskColour.
Canvas coefficient_figure(std::size_t height, std::size_t width, std::size_t k, std::span<const float> coefficients,
                          std::span<const std::uint8_t> mask, bool nmf);

}  // namespace specula::stats
