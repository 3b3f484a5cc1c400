#pragma once
// Pictures people look at: spectra rendered to sRGB with exposure (fixed or automatic), tone and gamut mapping,
// masked pixels in one colour, error ramps, and panels side by side. Every command, the viewer and the Python
// module draw through these, so one image looks the same wherever it is shown.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "specula/core/colour.h"

namespace specula {

using Rgb8 = std::array<std::uint8_t, 3>;

/// The one colour of masked (invalid) pixels in every picture: dark red, as the reference's figure 7.1 marks them.
inline constexpr Rgb8 kMaskColour{128, 0, 0};

/// How spectra become a picture. The illuminant lights reflectance (ignored for radiance).
struct PreviewSettings {
  Eigen::VectorXd illuminant;            ///< SPD on the spectra's grid
  std::optional<double> exposure_stops;  ///< empty: automatic (see auto_exposure_stops)
  ToneMap tone = ToneMap::clip;
  bool desaturate = true;    ///< gamut mapping by desaturation, else clipping
  bool adapt_to_d65 = true;  ///< Bradford-adapt the scene white to D65
};

/// A rendered picture: 8-bit sRGB and the linear RGB behind it (3 values per pixel, row-major).
struct Picture {
  std::size_t width = 0, height = 0;
  std::vector<std::uint8_t> srgb8;
  std::vector<float> linear;
};

/// Parses an exposure: "auto" (empty result) or stops between -64 and 64; UsageError naming `exposure` otherwise.
std::optional<double> parse_exposure(std::string_view spec);
/// Parses a tone map name, "clip" or "reinhard"; UsageError naming `tone` otherwise.
ToneMap parse_tone(std::string_view name);

/// The q-quantile (0 <= q <= 1) of values, or 0 when there are none; reorders values.
double quantile(std::vector<float>& values, double q);
/// Automatic exposure: the stops that map the 99th-percentile luminance (Y, column 1 of xyz) of the pixels the
/// mask keeps (all when empty; else one byte per row, nonzero = valid) to 1; 0 for reflectance or no light.
double auto_exposure_stops(const Eigen::Ref<const RowMatrixX3f>& xyz, std::span<const std::uint8_t> mask,
                           SpectrumKind kind);

/// XYZ of spectra (N x B rows on `grid`) as `kind` says, under `illuminant` for reflectance; white gets the scene
/// white.
RowMatrixX3f spectra_to_xyz(const Eigen::Ref<const RowMatrixXf>& spectra, const WavelengthGrid& grid, SpectrumKind kind,
                            const Eigen::VectorXd& illuminant, Eigen::Vector3d& white);

/// Draws width x height pixels of XYZ (rows, row-major image order) relative to scene white `white`: the settings'
/// exposure (automatic when unset), tone and gamut mapping, masked pixels in kMaskColour.
Picture render_xyz(const Eigen::Ref<const RowMatrixX3f>& xyz, const Eigen::Vector3d& white, std::size_t width,
                   std::size_t height, std::span<const std::uint8_t> mask, SpectrumKind kind,
                   const PreviewSettings& settings);
/// Renders a width x height image of spectra (one row per pixel, row-major) on `grid`: XYZ, then render_xyz.
Picture render_preview(const Eigen::Ref<const RowMatrixXf>& spectra, std::size_t width, std::size_t height,
                       const WavelengthGrid& grid, SpectrumKind kind, std::span<const std::uint8_t> mask,
                       const PreviewSettings& settings);
/// One band of an image (`data` pixel-major, `bands` values a pixel) as grey sRGB8: each value over the 99th
/// percentile of the valid pixels' values (at least 1e-30), clipped to [0, 1] and encoded (encode_srgb8); pixels the
/// mask rejects (one byte a pixel; empty: none) in kMaskColour. UsageError for a band past the last.
std::vector<std::uint8_t> band_preview(std::span<const float> data, std::size_t bands, std::size_t band,
                                       std::span<const std::uint8_t> mask);
/// Paints the pixels the mask rejects (one byte per pixel, 0 = masked) of an 8-bit RGB picture in kMaskColour.
void paint_masked(std::span<std::uint8_t> srgb8, std::span<const std::uint8_t> mask);

/// The error-map ramp (black, blue, magenta, orange, yellow, white) at t in [0, 1] (clamped; NaN is 0).
Rgb8 heat(double t);

/// Linear sRGB of a rendering's XYZ: its white adapted to D65 (Bradford) and mapped to luminance 1.
Eigen::Matrix3d rendering_to_linear_srgb(const Eigen::Vector3d& white);

/// Pictures of one height side by side, `gap` white pixels apart: one RGB8 picture (UsageError on unequal heights).
Picture side_by_side(std::span<const Picture> panels, std::size_t gap);

}  // namespace specula
