#include "specula/core/preview.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "specula/core/error.h"

namespace specula {

std::optional<double> parse_exposure(std::string_view spec) {
  if (spec == "auto") return std::nullopt;
  const std::string s(spec);
  double v = 0;
  std::size_t pos = 0;
  try {
    v = std::stod(s, &pos);
  } catch (...) {
    pos = 0;
  }
  if (s.empty() || pos != s.size() || !(std::abs(v) <= 64))
    throw UsageError("exposure '" + s + "': give stops between -64 and 64, or auto");
  return v;
}

ToneMap parse_tone(std::string_view name) {
  if (name == "clip") return ToneMap::clip;
  if (name == "reinhard") return ToneMap::reinhard;
  throw UsageError("tone '" + std::string(name) + "': use clip or reinhard");
}

double quantile(std::vector<float>& values, double q) {
  if (values.empty()) return 0.0;
  const auto k = values.begin() + std::ptrdiff_t(double(values.size() - 1) * std::clamp(q, 0.0, 1.0));
  std::nth_element(values.begin(), k, values.end());
  return double(*k);
}

double auto_exposure_stops(const Eigen::Ref<const RowMatrixX3f>& xyz, std::span<const std::uint8_t> mask,
                           SpectrumKind kind) {
  if (kind == SpectrumKind::reflectance) return 0.0;
  if (!mask.empty() && mask.size() != std::size_t(xyz.rows()))
    throw UsageError("auto exposure: mask has " + std::to_string(mask.size()) + " entries for " +
                     std::to_string(xyz.rows()) + " pixels; give one per pixel or none");
  std::vector<float> y;
  y.reserve(std::size_t(xyz.rows()));
  for (Eigen::Index i = 0; i < xyz.rows(); ++i)
    if (mask.empty() || mask[std::size_t(i)]) y.push_back(xyz(i, 1));
  const double white = quantile(y, 0.99);
  return white > 0 ? -std::log2(white) : 0.0;
}

RowMatrixX3f spectra_to_xyz(const Eigen::Ref<const RowMatrixXf>& spectra, const WavelengthGrid& grid, SpectrumKind kind,
                            const Eigen::VectorXd& illuminant, Eigen::Vector3d& white) {
  const SpectrumToXyz to_xyz(grid, kind, illuminant);
  white = to_xyz.white();
  RowMatrixX3f xyz(spectra.rows(), 3);
  to_xyz.apply(spectra, xyz);
  return xyz;
}

std::vector<std::uint8_t> band_preview(std::span<const float> data, std::size_t bands, std::size_t band,
                                       std::span<const std::uint8_t> mask) {
  if (band >= bands)
    throw UsageError("band_preview: band " + std::to_string(band) + " of " + std::to_string(bands) + " bands");
  const std::size_t n = data.size() / bands;
  std::vector<float> v;
  v.reserve(n);
  for (std::size_t p = 0; p < n; ++p)
    if (mask.empty() || mask[p]) v.push_back(data[p * bands + band]);
  const double top = std::max(quantile(v, 0.99), 1e-30);
  std::vector<double> grey(3 * n);
  for (std::size_t p = 0; p < n; ++p)
    grey[3 * p] = grey[3 * p + 1] = grey[3 * p + 2] = std::clamp(double(data[p * bands + band]) / top, 0.0, 1.0);
  std::vector<std::uint8_t> rgb(3 * n);
  encode_srgb8(std::span<const double>(grey), std::vector<std::uint8_t>(n, 1), 0.0, rgb);
  paint_masked(rgb, mask);
  return rgb;
}

void paint_masked(std::span<std::uint8_t> srgb8, std::span<const std::uint8_t> mask) {
  if (mask.empty()) return;
  if (srgb8.size() != 3 * mask.size())
    throw UsageError("paint_masked: " + std::to_string(srgb8.size()) + " bytes for a mask of " +
                     std::to_string(mask.size()) + " pixels; give 3 bytes per pixel");
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (!mask[i]) std::copy(kMaskColour.begin(), kMaskColour.end(), srgb8.begin() + std::ptrdiff_t(3 * i));
}

Picture render_xyz(const Eigen::Ref<const RowMatrixX3f>& xyz, const Eigen::Vector3d& white, std::size_t width,
                   std::size_t height, std::span<const std::uint8_t> mask, SpectrumKind kind,
                   const PreviewSettings& settings) {
  if (std::size_t(xyz.rows()) != width * height)
    throw UsageError("render: " + std::to_string(xyz.rows()) + " colours for a " + std::to_string(width) + " x " +
                     std::to_string(height) + " picture; give one per pixel");
  DisplayOptions d;
  d.tone = settings.tone;
  d.desaturate = settings.desaturate;
  d.adapt_to_d65 = settings.adapt_to_d65;
  d.exposure_stops = settings.exposure_stops ? *settings.exposure_stops : auto_exposure_stops(xyz, mask, kind);
  Picture p;
  p.width = width;
  p.height = height;
  p.srgb8.resize(3 * width * height);
  RowMatrixX3f lin(xyz.rows(), 3);
  xyz_to_display(xyz, white, d, lin, p.srgb8);
  p.linear.assign(lin.data(), lin.data() + lin.size());
  paint_masked(p.srgb8, mask);
  return p;
}

Picture render_preview(const Eigen::Ref<const RowMatrixXf>& spectra, std::size_t width, std::size_t height,
                       const WavelengthGrid& grid, SpectrumKind kind, std::span<const std::uint8_t> mask,
                       const PreviewSettings& settings) {
  Eigen::Vector3d white;
  const RowMatrixX3f xyz = spectra_to_xyz(spectra, grid, kind, settings.illuminant, white);
  return render_xyz(xyz, white, width, height, mask, kind, settings);
}

Rgb8 heat(double t) {
  static const double stops[6][3] = {{0, 0, 0},      {30, 30, 140},  {150, 40, 150},
                                     {240, 100, 40}, {250, 220, 60}, {255, 255, 255}};
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 5.0;
  const int i = std::min(4, int(t));
  const double f = t - i;
  Rgb8 c{};
  for (int k = 0; k < 3; ++k)
    c[std::size_t(k)] = std::uint8_t(std::lround(stops[i][k] * (1 - f) + stops[i + 1][k] * f));
  return c;
}

Eigen::Matrix3d rendering_to_linear_srgb(const Eigen::Vector3d& white) {
  if (!(white.y() > 0))
    throw UsageError("rendering white has luminance " + std::to_string(white.y()) + "; it must be positive");
  return xyz_to_linear_srgb() * bradford_adaptation(white / white.y(), d65_white()) / white.y();
}

Picture side_by_side(std::span<const Picture> panels, std::size_t gap) {
  Picture out;
  if (panels.empty()) return out;
  out.height = panels.front().height;
  for (std::size_t i = 0; i < panels.size(); ++i) {
    if (panels[i].height != out.height)
      throw UsageError("side_by_side: panel " + std::to_string(i) + " is " + std::to_string(panels[i].height) +
                       " pixels high, panel 0 " + std::to_string(out.height) + "; panels must be equally high");
    out.width += panels[i].width + (i ? gap : 0);
  }
  out.srgb8.assign(3 * out.width * out.height, 255);
  std::size_t x0 = 0;
  for (const Picture& p : panels) {
    for (std::size_t y = 0; y < p.height; ++y)
      std::copy_n(p.srgb8.begin() + std::ptrdiff_t(3 * y * p.width), 3 * p.width,
                  out.srgb8.begin() + std::ptrdiff_t(3 * (y * out.width + x0)));
    x0 += p.width + gap;
  }
  return out;
}

}  // namespace specula
