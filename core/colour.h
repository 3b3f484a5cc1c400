#pragma once
// Colour: spectra -> CIE XYZ -> sRGB for display (exposure, tone mapping, gamut mapping by desaturation
// as reference section 2.3 does), CIELAB and CIEDE2000.
#include <Eigen/Core>
#include <cstdint>
#include <span>

#include "specula/core/cie.h"
#include "specula/core/wavelengths.h"

namespace specula {

using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowMatrixX3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// What the values of a spectrum mean: a reflectance factor (lit by an illuminant for display) or a radiance.
enum class SpectrumKind { reflectance, radiance };

/// XYZ (Y = 1) of the D65 white, CIE 1931 observer: the target of adaptation before the sRGB matrix.
Eigen::Vector3d d65_white();
/// XYZ -> linear sRGB (IEC 61966-2-1, D65 white).
Eigen::Matrix3d xyz_to_linear_srgb();
/// Bradford chromatic adaptation matrix taking colours seen under white `from` to white `to` (both XYZ).
Eigen::Matrix3d bradford_adaptation(const Eigen::Vector3d& from_white, const Eigen::Vector3d& to_white);
/// sRGB transfer function (linear -> encoded), input clamped to [0, 1].
double srgb_encode(double linear);
/// Inverse sRGB transfer function (encoded -> linear).
double srgb_decode(double encoded);
/// CIE 1976 L*a*b* of xyz relative to reference white `white` (XYZ).
Eigen::Vector3d xyz_to_lab(const Eigen::Vector3d& xyz, const Eigen::Vector3d& white);
/// CIEDE2000 colour difference (kL = kC = kH = 1), Sharma et al. 2005.
double ciede2000(const Eigen::Vector3d& lab1, const Eigen::Vector3d& lab2);

/// Linear map from spectra on a grid to CIE XYZ by trapezoid quadrature of the CMFs.
/// Reflectance: XYZ = k * sum(cmf * illuminant * r), k such that a perfect white has Y = 1.
/// Radiance: XYZ = k * sum(cmf * s), k such that the flat spectrum s = 1 has Y = 1 (illuminant ignored).
class SpectrumToXyz {
 public:
  /// Throws UsageError if illuminant.size() != grid.size() for reflectance.
  SpectrumToXyz(const WavelengthGrid& grid, SpectrumKind kind, const Eigen::VectorXd& illuminant,
                Observer observer = Observer::cie1931_2deg);
  /// The 3 x B matrix W with XYZ = W * spectrum.
  const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights() const { return w_; }
  /// XYZ of the scene white: the illuminant itself for reflectance (Y = 1), equal energy for radiance.
  const Eigen::Vector3d& white() const { return white_; }
  /// Converts rows of spectra (N x B) into rows of XYZ (N x 3); xyz must already be N x 3.
  void apply(const Eigen::Ref<const RowMatrixXf>& spectra, Eigen::Ref<RowMatrixX3f> xyz) const;

 private:
  Eigen::Matrix<double, 3, Eigen::Dynamic> w_;
  Eigen::Vector3d white_;
};

enum class ToneMap { clip, reinhard };

/// How linear XYZ becomes display sRGB.
struct DisplayOptions {
  double exposure_stops = 0.0;   ///< multiply by 2^exposure_stops before tone mapping
  ToneMap tone = ToneMap::clip;  ///< Reinhard acts on luminance: Y' = Y / (1 + Y)
  bool adapt_to_d65 = true;      ///< Bradford-adapt the scene white to D65 before the sRGB matrix
  bool desaturate = true;        ///< bring out-of-gamut colours in by mixing toward grey of equal luminance
};

/// XYZ rows -> display sRGB: exposure, tone map, adaptation from `scene_white`, gamut mapping by
/// desaturation (else clipping), sRGB encoding. linear_out (N x 3, optional: may be empty) gets the
/// linear in-gamut RGB; srgb8_out (3N bytes, optional) gets the encoded 8-bit values.
void xyz_to_display(const Eigen::Ref<const RowMatrixX3f>& xyz, const Eigen::Vector3d& scene_white,
                    const DisplayOptions& options, Eigen::Ref<RowMatrixX3f> linear_out,
                    std::span<std::uint8_t> srgb8_out);

/// Moves linear RGB toward the grey of equal luminance (Rec.709 Y weights) just enough to lie in [0, 1]^3;
/// luminance above 1 is clipped to white. Returns the mapped colour.
Eigen::Vector3d desaturate_into_gamut(const Eigen::Vector3d& linear_rgb);

/// 8-bit sRGB of linear RGB pixels (3 values each) scaled by 2^exposure_stops, clipped to [0, 1] and encoded (rounded);
/// pixels whose `covered` entry is 0 get `background` in every channel. Throws UsageError unless linear and out hold
/// 3 values per entry of `covered`.
void encode_srgb8(std::span<const float> linear, std::span<const std::uint8_t> covered, double exposure_stops,
                  std::span<std::uint8_t> out, std::uint8_t background = 24);
/// As above for linear values in double precision.
void encode_srgb8(std::span<const double> linear, std::span<const std::uint8_t> covered, double exposure_stops,
                  std::span<std::uint8_t> out, std::uint8_t background = 24);

}  // namespace specula
