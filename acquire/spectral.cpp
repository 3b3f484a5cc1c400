#include "specula/acquire/spectral.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

#include "specula/core/error.h"

namespace specula::acquire {

SpectralModel parse_spectral_model(const std::string& name) {
  if (name == "delta") return SpectralModel::delta;
  if (name == "factored") return SpectralModel::factored;
  throw UsageError("spectral model '" + name + "': use delta (eq 4.4) or factored (eq 4.6)");
}

double Tabulated::at(double l) const {
  if (nm.empty()) return 0;
  if (l <= nm.front()) return value.front();
  if (l >= nm.back()) return value.back();
  const auto i = std::size_t(std::upper_bound(nm.begin(), nm.end(), l) - nm.begin());
  const double t = (l - nm[i - 1]) / (nm[i] - nm[i - 1]);
  return value[i - 1] + t * (value[i] - value[i - 1]);
}

namespace {

void check(std::span<const double> bands, const Eigen::MatrixXd& measured, const Eigen::MatrixXd& reflectance) {
  if (bands.empty() || measured.cols() != Eigen::Index(bands.size()) || reflectance.rows() != measured.rows() ||
      reflectance.cols() != measured.cols() || measured.rows() < 1)
    throw UsageError("spectral calibration: give targets x bands measurements and reflectances, at least one target");
  if (!measured.allFinite() || !reflectance.allFinite())
    throw InputError("spectral calibration: non-finite target data");
}

// w = argmin sum_i (H_i - w a_i)^2 per band.
Eigen::VectorXd least_squares_scale(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& model) {
  Eigen::VectorXd w(measured.cols());
  for (Eigen::Index j = 0; j < measured.cols(); ++j) {
    const double den = model.col(j).squaredNorm();
    if (!(den > 0)) throw InputError("spectral calibration: the targets reflect nothing at band " + std::to_string(j));
    w[j] = measured.col(j).dot(model.col(j)) / den;
    if (!(w[j] > 0))
      throw InputError("spectral calibration: band " + std::to_string(j) + " has no signal on the targets");
  }
  return w;
}

}  // namespace

SpectralCalibration fit_delta(std::span<const double> bands, const Tabulated& light, const Eigen::MatrixXd& measured,
                              const Eigen::MatrixXd& reflectance) {
  check(bands, measured, reflectance);
  const Eigen::Index n = Eigen::Index(bands.size());
  Eigen::MatrixXd model = reflectance;
  for (Eigen::Index j = 0; j < n; ++j) model.col(j) *= light.at(bands[std::size_t(j)]);
  SpectralCalibration c;
  c.model = SpectralModel::delta;
  c.bands.assign(bands.begin(), bands.end());
  c.scale = least_squares_scale(measured, model);
  c.recovery = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index j = 0; j < n; ++j) c.recovery(j, j) = 1 / (c.scale[j] * light.at(bands[std::size_t(j)]));
  return c;
}

SpectralCalibration fit_factored(std::span<const double> bands, const Tabulated& light,
                                 std::span<const Tabulated> transmission, const Eigen::MatrixXd& measured,
                                 const Eigen::MatrixXd& reflectance) {
  check(bands, measured, reflectance);
  const Eigen::Index n = Eigen::Index(bands.size());
  if (transmission.size() != bands.size()) throw UsageError("factored model: one transmission curve per band");
  Tabulated rho;
  rho.nm.assign(bands.begin(), bands.end());
  Eigen::MatrixXd model(measured.rows(), n);
  for (Eigen::Index i = 0; i < measured.rows(); ++i) {
    rho.value.clear();
    for (Eigen::Index j = 0; j < n; ++j) rho.value.push_back(reflectance(i, j));
    for (Eigen::Index j = 0; j < n; ++j) {
      const Tabulated& t = transmission[std::size_t(j)];
      if (t.nm.size() < 2) throw InputError("factored model: a transmission curve needs at least two points");
      double s = 0;
      for (std::size_t k = 0; k + 1 < t.nm.size(); ++k) {
        const double a = t.nm[k], b = t.nm[k + 1];
        s += 0.5 * (b - a) * (t.value[k] * light.at(a) * rho.at(a) + t.value[k + 1] * light.at(b) * rho.at(b));
      }
      model(i, j) = s;
    }
  }
  SpectralCalibration c;
  c.model = SpectralModel::factored;
  c.bands.assign(bands.begin(), bands.end());
  c.scale = least_squares_scale(measured, model);
  // Eq 4.7 with f piecewise linear between the bands (f = sum_k f_k phi_k, phi_k the hat functions; constant
  // beyond the end bands): R L [j, k] = c_j integral of T_j L phi_k, on T_j's own tabulation. This is the model
  // the fit above assumed for the targets, and it stays exact when passbands are narrower than the band spacing,
  // where sampling T_j at the band centres (the reference's quadrature) is not.
  Eigen::MatrixXd rl = Eigen::MatrixXd::Zero(n, n);
  auto hat = [&](Eigen::Index k, double l) {
    const double x = bands[std::size_t(k)];
    if (l <= x) {
      if (k == 0) return 1.0;
      const double a = bands[std::size_t(k - 1)];
      return l <= a ? 0.0 : (l - a) / (x - a);
    }
    if (k + 1 == n) return 1.0;
    const double b = bands[std::size_t(k + 1)];
    return l >= b ? 0.0 : (b - l) / (b - x);
  };
  for (Eigen::Index j = 0; j < n; ++j) {
    const Tabulated& t = transmission[std::size_t(j)];
    for (std::size_t q = 0; q + 1 < t.nm.size(); ++q) {
      // Simpson on each tabulation interval (the hat's kink is resolved when the tabulation is finer than the bands).
      const double a = t.nm[q], b = t.nm[q + 1], m = 0.5 * (a + b);
      const double ta = t.value[q], tb = t.value[q + 1], tm = 0.5 * (ta + tb);
      for (Eigen::Index k = 0; k < n; ++k)
        rl(j, k) += c.scale[j] * (b - a) / 6 *
                    (ta * light.at(a) * hat(k, a) + 4 * tm * light.at(m) * hat(k, m) + tb * light.at(b) * hat(k, b));
    }
  }
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(rl);
  if (!lu.isInvertible())
    throw InputError("factored model: R L is singular on the band grid (passbands too narrow for the band spacing?)");
  c.recovery = lu.inverse();
  return c;
}

double spectral_rms(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  if (a.size() != b.size() || a.size() == 0) throw UsageError("spectral_rms: two spectra on the same bands");
  return std::sqrt((a - b).squaredNorm() / double(a.size()));
}

}  // namespace specula::acquire
