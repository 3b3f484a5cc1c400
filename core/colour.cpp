#include "specula/core/colour.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula {
namespace {

std::string describe_xyz(const Eigen::Vector3d& v) {
  return "(" + num(v[0]) + ", " + num(v[1]) + ", " + num(v[2]) + ")";
}

Eigen::Vector3d xy_to_xyz(double x, double y) { return {x / y, 1.0, (1.0 - x - y) / y}; }

}  // namespace

Eigen::Vector3d d65_white() { return xy_to_xyz(0.31271, 0.32902); }

namespace {

Eigen::Matrix3d bradford_matrix() {
  Eigen::Matrix3d m;
  m << 0.8951, 0.2664, -0.1614, -0.7502, 1.7135, 0.0367, 0.0389, -0.0685, 1.0296;
  return m;
}

constexpr double kLumR = 0.2126, kLumG = 0.7152, kLumB = 0.0722;

inline void desaturate(double& r, double& g, double& b) {
  if (r >= 0.0 && r <= 1.0 && g >= 0.0 && g <= 1.0 && b >= 0.0 && b <= 1.0) return;
  const double y = kLumR * r + kLumG * g + kLumB * b;
  if (!(y > 0.0)) {
    r = g = b = 0.0;
    return;
  }
  if (y >= 1.0) {
    r = g = b = 1.0;
    return;
  }
  // The largest channel limits the approach to 1, the smallest the approach to 0.
  const double hi = std::max({r, g, b}), lo = std::min({r, g, b});
  double s = 1.0;
  if (hi > 1.0) s = (1.0 - y) / (hi - y);
  if (lo < 0.0) s = std::min(s, y / (y - lo));
  r = std::clamp(y + s * (r - y), 0.0, 1.0);
  g = std::clamp(y + s * (g - y), 0.0, 1.0);
  b = std::clamp(y + s * (b - y), 0.0, 1.0);
}

inline double clip01(double v) { return v > 0.0 ? (v < 1.0 ? v : 1.0) : 0.0; }

// Rounded 8-bit sRGB codes of linear values in [0, 1]: t[c] is the linear value at which the code steps
// from c to c + 1; a 4096-entry table gives the code at the start of each bin, and the few steps inside
// a bin are resolved by comparison, so the result equals rounding srgb_encode exactly.
struct Srgb8Encoder {
  static constexpr int kBins = 4096;
  std::array<double, 256> t;
  std::array<std::uint8_t, kBins> start;
  Srgb8Encoder() {
    for (int c = 0; c < 255; ++c) t[std::size_t(c)] = srgb_decode((c + 0.5) / 255.0);
    t[255] = 2.0;
    int c = 0;
    for (int i = 0; i < kBins; ++i) {
      while (c < 255 && double(i) / kBins >= t[std::size_t(c)]) ++c;
      start[std::size_t(i)] = std::uint8_t(c);
    }
  }
  std::uint8_t code(double linear) const {
    unsigned c = start[std::size_t(std::clamp(int(linear * kBins), 0, kBins - 1))];
    while (linear >= t[c]) ++c;
    return std::uint8_t(c);
  }
};

}  // namespace

Eigen::Matrix3d xyz_to_linear_srgb() {
  static const Eigen::Matrix3d m = [] {
    // IEC 61966-2-1 primaries and white (x, y); columns of P are the primaries' XYZ at Y = 1.
    Eigen::Matrix3d p;
    p.col(0) = xy_to_xyz(0.64, 0.33);
    p.col(1) = xy_to_xyz(0.30, 0.60);
    p.col(2) = xy_to_xyz(0.15, 0.06);
    const Eigen::Vector3d scale = p.lu().solve(xy_to_xyz(0.3127, 0.3290));
    const Eigen::Matrix3d rgb_to_xyz = p * scale.asDiagonal();
    return Eigen::Matrix3d(rgb_to_xyz.inverse());
  }();
  return m;
}

Eigen::Matrix3d bradford_adaptation(const Eigen::Vector3d& from_white, const Eigen::Vector3d& to_white) {
  const Eigen::Matrix3d m = bradford_matrix();
  const Eigen::Vector3d from = m * from_white;
  const Eigen::Vector3d to = m * to_white;
  if (!from_white.allFinite() || !(from.minCoeff() > 0.0))
    throw UsageError("Bradford adaptation: source white XYZ " + describe_xyz(from_white) +
                     " is not a valid white; give finite XYZ of a light with Y > 0");
  if (!to_white.allFinite() || !(to.minCoeff() > 0.0))
    throw UsageError("Bradford adaptation: target white XYZ " + describe_xyz(to_white) +
                     " is not a valid white; give finite XYZ of a light with Y > 0");
  return m.inverse() * to.cwiseQuotient(from).asDiagonal() * m;
}

double srgb_encode(double linear) {
  if (!(linear > 0.0)) return 0.0;
  if (linear >= 1.0) return 1.0;
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

double srgb_decode(double encoded) {
  return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

Eigen::Vector3d xyz_to_lab(const Eigen::Vector3d& xyz, const Eigen::Vector3d& white) {
  if (!white.allFinite() || !(white.minCoeff() > 0.0))
    throw UsageError("CIELAB reference white XYZ " + describe_xyz(white) +
                     " is invalid; all three components must be finite and positive");
  constexpr double eps = 216.0 / 24389.0;
  constexpr double kappa = 24389.0 / 27.0;
  auto f = [](double t) { return t > eps ? std::cbrt(t) : (kappa * t + 16.0) / 116.0; };
  const double fx = f(xyz[0] / white[0]);
  const double fy = f(xyz[1] / white[1]);
  const double fz = f(xyz[2] / white[2]);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

double ciede2000(const Eigen::Vector3d& lab1, const Eigen::Vector3d& lab2) {
  constexpr double deg = std::numbers::pi / 180.0;
  constexpr double pow25_7 = 6103515625.0;  // 25^7
  const double l1 = lab1[0], a1 = lab1[1], b1 = lab1[2];
  const double l2 = lab2[0], a2 = lab2[1], b2 = lab2[2];

  const double c_bar = 0.5 * (std::hypot(a1, b1) + std::hypot(a2, b2));
  const double c_bar7 = std::pow(c_bar, 7.0);
  const double g = 0.5 * (1.0 - std::sqrt(c_bar7 / (c_bar7 + pow25_7)));
  const double a1p = (1.0 + g) * a1, a2p = (1.0 + g) * a2;
  const double c1p = std::hypot(a1p, b1), c2p = std::hypot(a2p, b2);
  auto hue = [](double b, double a) {
    if (a == 0.0 && b == 0.0) return 0.0;
    const double h = std::atan2(b, a) / (std::numbers::pi / 180.0);
    return h < 0.0 ? h + 360.0 : h;
  };
  const double h1p = hue(b1, a1p), h2p = hue(b2, a2p);

  const double dl = l2 - l1;
  const double dc = c2p - c1p;
  const double cc = c1p * c2p;
  double dh = 0.0;
  if (cc != 0.0) {
    dh = h2p - h1p;
    if (dh > 180.0)
      dh -= 360.0;
    else if (dh < -180.0)
      dh += 360.0;
  }
  const double dH = 2.0 * std::sqrt(cc) * std::sin(0.5 * dh * deg);

  const double l_bar = 0.5 * (l1 + l2);
  const double cp_bar = 0.5 * (c1p + c2p);
  double h_bar = h1p + h2p;
  if (cc != 0.0) {
    if (std::abs(h1p - h2p) <= 180.0)
      h_bar *= 0.5;
    else if (h_bar < 360.0)
      h_bar = 0.5 * (h_bar + 360.0);
    else
      h_bar = 0.5 * (h_bar - 360.0);
  }
  const double t = 1.0 - 0.17 * std::cos((h_bar - 30.0) * deg) + 0.24 * std::cos(2.0 * h_bar * deg) +
                   0.32 * std::cos((3.0 * h_bar + 6.0) * deg) - 0.20 * std::cos((4.0 * h_bar - 63.0) * deg);
  const double d_theta = 30.0 * std::exp(-std::pow((h_bar - 275.0) / 25.0, 2.0));
  const double cp_bar7 = std::pow(cp_bar, 7.0);
  const double rc = 2.0 * std::sqrt(cp_bar7 / (cp_bar7 + pow25_7));
  const double l50 = (l_bar - 50.0) * (l_bar - 50.0);
  const double sl = 1.0 + 0.015 * l50 / std::sqrt(20.0 + l50);
  const double sc = 1.0 + 0.045 * cp_bar;
  const double sh = 1.0 + 0.015 * cp_bar * t;
  const double rt = -std::sin(2.0 * d_theta * deg) * rc;
  const double tl = dl / sl, tc = dc / sc, th = dH / sh;
  return std::sqrt(tl * tl + tc * tc + th * th + rt * tc * th);
}

SpectrumToXyz::SpectrumToXyz(const WavelengthGrid& grid, SpectrumKind kind, const Eigen::VectorXd& illuminant,
                             Observer observer) {
  if (grid.empty()) throw UsageError("spectrum to XYZ: the wavelength grid is empty");
  const Eigen::MatrixX3d bar = cmf(grid, observer);
  Eigen::VectorXd weight = trapezoid_weights(grid);
  if (kind == SpectrumKind::reflectance) {
    if (illuminant.size() != Eigen::Index(grid.size()))
      throw UsageError("spectrum to XYZ: the illuminant has " + std::to_string(illuminant.size()) +
                       " values but the grid (" + grid.describe() + ") has " + std::to_string(grid.size()) +
                       "; sample the illuminant on the same grid");
    if (!illuminant.allFinite())
      throw UsageError("spectrum to XYZ: the illuminant has non-finite values; give a finite SPD");
    weight = weight.cwiseProduct(illuminant);
  }
  w_ = (bar.transpose() * weight.asDiagonal());
  const double y_white = w_.row(1).sum();
  if (!(y_white > 0.0))
    throw UsageError("spectrum to XYZ: a white has no luminance on " + grid.describe() +
                     (kind == SpectrumKind::reflectance ? " under this illuminant" : "") +
                     "; use wavelengths inside 360-830 nm where the eye responds");
  w_ /= y_white;
  white_ = w_.rowwise().sum();
}

void SpectrumToXyz::apply(const Eigen::Ref<const RowMatrixXf>& spectra, Eigen::Ref<RowMatrixX3f> xyz) const {
  if (spectra.cols() != w_.cols())
    throw UsageError("spectrum to XYZ: spectra have " + std::to_string(spectra.cols()) + " bands, expected " +
                     std::to_string(w_.cols()));
  if (xyz.rows() != spectra.rows())
    throw UsageError("spectrum to XYZ: output has " + std::to_string(xyz.rows()) + " rows for " +
                     std::to_string(spectra.rows()) + " spectra; size it N x 3");
  const Eigen::Matrix<float, Eigen::Dynamic, 3> wt = w_.transpose().cast<float>();
  xyz.noalias() = spectra * wt;
}

void xyz_to_display(const Eigen::Ref<const RowMatrixX3f>& xyz, const Eigen::Vector3d& scene_white,
                    const DisplayOptions& options, Eigen::Ref<RowMatrixX3f> linear_out,
                    std::span<std::uint8_t> srgb8_out) {
  const Eigen::Index n = xyz.rows();
  if (linear_out.rows() != 0 && linear_out.rows() != n)
    throw UsageError("display conversion: linear output has " + std::to_string(linear_out.rows()) + " rows for " +
                     std::to_string(n) + " colours; size it N x 3 or leave it empty");
  if (!srgb8_out.empty() && srgb8_out.size() != std::size_t(3 * n))
    throw UsageError("display conversion: 8-bit output has " + std::to_string(srgb8_out.size()) + " bytes for " +
                     std::to_string(n) + " colours; give 3 N bytes or none");
  if (!std::isfinite(options.exposure_stops))
    throw UsageError("display conversion: exposure " + num(options.exposure_stops) +
                     " stops is not finite; give a finite number of stops");

  Eigen::Matrix3d m = xyz_to_linear_srgb();
  if (options.adapt_to_d65) m = m * bradford_adaptation(scene_white, d65_white());
  double k[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) k[3 * r + c] = m(r, c);
  const double scale = std::exp2(options.exposure_stops);
  const bool reinhard = options.tone == ToneMap::reinhard;
  const bool desat = options.desaturate;
  const bool want_linear = linear_out.rows() != 0;
  std::uint8_t* out8 = srgb8_out.empty() ? nullptr : srgb8_out.data();
  static const Srgb8Encoder encoder;

  for (Eigen::Index i = 0; i < n; ++i) {
    const double x = xyz(i, 0), y = xyz(i, 1), z = xyz(i, 2);
    double f = scale;
    if (reinhard) {
      const double lum = scale * y;
      if (lum > 0.0) f /= 1.0 + lum;
    }
    double r = f * (k[0] * x + k[1] * y + k[2] * z);
    double g = f * (k[3] * x + k[4] * y + k[5] * z);
    double b = f * (k[6] * x + k[7] * y + k[8] * z);
    if (desat) {
      desaturate(r, g, b);
    } else {
      r = clip01(r);
      g = clip01(g);
      b = clip01(b);
    }
    if (want_linear) {
      linear_out(i, 0) = float(r);
      linear_out(i, 1) = float(g);
      linear_out(i, 2) = float(b);
    }
    if (out8) {
      out8[3 * i] = encoder.code(r);
      out8[3 * i + 1] = encoder.code(g);
      out8[3 * i + 2] = encoder.code(b);
    }
  }
}

Eigen::Vector3d desaturate_into_gamut(const Eigen::Vector3d& linear_rgb) {
  double r = linear_rgb[0], g = linear_rgb[1], b = linear_rgb[2];
  desaturate(r, g, b);
  return {r, g, b};
}

namespace {

template <typename T>
void encode_srgb8_of(std::span<const T> linear, std::span<const std::uint8_t> covered, double exposure_stops,
                     std::span<std::uint8_t> out, std::uint8_t background) {
  if (linear.size() != 3 * covered.size() || out.size() != linear.size())
    throw UsageError("encode_srgb8: " + std::to_string(linear.size()) + " linear values and " +
                     std::to_string(out.size()) + " bytes for " + std::to_string(covered.size()) +
                     " pixels; give 3 of each per pixel");
  const double gain = std::exp2(exposure_stops);
  for (std::size_t i = 0; i < covered.size(); ++i)
    for (std::size_t c = 0; c < 3; ++c)
      out[3 * i + c] =
          covered[i] ? std::uint8_t(std::lround(255 * srgb_encode(gain * double(linear[3 * i + c])))) : background;
}

}  // namespace

void encode_srgb8(std::span<const float> linear, std::span<const std::uint8_t> covered, double exposure_stops,
                  std::span<std::uint8_t> out, std::uint8_t background) {
  encode_srgb8_of(linear, covered, exposure_stops, out, background);
}

void encode_srgb8(std::span<const double> linear, std::span<const std::uint8_t> covered, double exposure_stops,
                  std::span<std::uint8_t> out, std::uint8_t background) {
  encode_srgb8_of(linear, covered, exposure_stops, out, background);
}

}  // namespace specula
