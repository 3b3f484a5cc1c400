#include "specula/core/relight.h"

#include <Eigen/LU>
#include <algorithm>

#include "specula/core/error.h"
#include "specula/core/preview.h"
#include "specula/core/text.h"

namespace specula {

Relighting relight(const Eigen::Ref<const RowMatrixXf>& spectra, const WavelengthGrid& grid, SpectrumKind kind,
                   std::span<const std::uint8_t> mask, const Eigen::VectorXd& from, const Eigen::VectorXd& to) {
  const Eigen::Index n = spectra.rows(), nb = spectra.cols();
  if (std::size_t(nb) != grid.size() || from.size() != nb || to.size() != nb)
    throw UsageError("relight: spectra have " + std::to_string(nb) + " bands, the grid " + std::to_string(grid.size()) +
                     ", light `from` " + std::to_string(from.size()) + " and light `to` " + std::to_string(to.size()) +
                     "; all must agree");
  if (!mask.empty() && mask.size() != std::size_t(n))
    throw UsageError("relight: mask has " + std::to_string(mask.size()) + " entries for " + std::to_string(n) +
                     " spectra; give one per spectrum or none");
  const bool reflectance = kind == SpectrumKind::reflectance;
  if (!reflectance)
    for (Eigen::Index b = 0; b < nb; ++b)
      if (!(from[b] > 0))
        throw InputError("relight: light `from` is " + num(from[b]) + " at " + num(grid[std::size_t(b)]) +
                         " nm, so it cannot be divided out of radiance; give a light that is positive at every band");
  const auto valid = [&](Eigen::Index i) { return mask.empty() || mask[std::size_t(i)] != 0; };

  // Reflectance f: the data itself, or the radiance with the old light divided out (eq 4.9).
  RowMatrixXf f = reflectance ? RowMatrixXf(spectra)
                              : RowMatrixXf(spectra.array().rowwise() / from.transpose().cast<float>().array());
  const SpectrumToXyz under_from(grid, SpectrumKind::reflectance, from);
  const SpectrumToXyz under_to(grid, SpectrumKind::reflectance, to);
  Relighting r;
  r.original.resize(n, 3);
  r.spectral.resize(n, 3);
  r.rgb.resize(n, 3);
  r.white_from = under_from.white();
  r.white_to = under_to.white();
  under_from.apply(f, r.original);
  if (!reflectance) {
    // Radiance has no absolute scale: its 99th-percentile luminance under the old light is called white (Y = 1),
    // so the colour differences do not depend on the data's units.
    const double stops = auto_exposure_stops(r.original, mask, SpectrumKind::radiance);
    const float scale = float(std::exp2(stops));
    f *= scale;
    r.original *= scale;
  }
  under_to.apply(f, r.spectral);

  // RGB camera: linear-sRGB matching curves M * cmf; per-channel scaling by the lights' responses (eq 4.10).
  const Eigen::Matrix3d m = xyz_to_linear_srgb();
  const SpectrumToXyz radiance_to(grid, SpectrumKind::radiance, to);
  const Eigen::Matrix<double, 3, Eigen::Dynamic> camera = m * radiance_to.weights();
  const Eigen::Vector3d resp_from = camera * from, resp_to = camera * to;
  const double y_to = (radiance_to.weights() * to)(1);
  const Eigen::Vector3d gain = resp_to.cwiseQuotient(resp_from) / y_to;
  const Eigen::Matrix3f to_xyz = (m.inverse() * gain.asDiagonal()).cast<float>();
  const Eigen::Matrix<float, 3, Eigen::Dynamic> cam_f = camera.cast<float>();
  const Eigen::RowVectorXf from_f = from.transpose().cast<float>();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3f captured = cam_f * f.row(i).cwiseProduct(from_f).transpose();
    r.rgb.row(i) = (to_xyz * captured).transpose();
  }

  // CIEDE2000 between the two relit images, relative to the new light's white.
  r.ciede2000.assign(std::size_t(n), 0.0);
  std::vector<double> de;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!valid(i)) continue;
    const double d = ciede2000(xyz_to_lab(r.spectral.row(i).transpose().cast<double>(), r.white_to),
                               xyz_to_lab(r.rgb.row(i).transpose().cast<double>(), r.white_to));
    de.push_back(d);
    r.ciede2000[std::size_t(i)] = d;
  }
  if (de.empty()) throw InputError("relight: no valid pixel to relight");
  r.pixels = de.size();
  for (double d : de) r.mean_ciede2000 += d;
  r.mean_ciede2000 /= double(de.size());
  std::sort(de.begin(), de.end());
  r.p95_ciede2000 = de[std::size_t(0.95 * double(de.size() - 1))];
  r.max_ciede2000 = de.back();
  return r;
}

}  // namespace specula
