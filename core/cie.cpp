#include "specula/core/cie.h"

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula {
namespace {

// log(exp(a) - 1) for a > 0 without overflow.
double log_expm1(double a) { return a > 30.0 ? a + std::log1p(-std::exp(-a)) : std::log(std::expm1(a)); }

}  // namespace

Eigen::MatrixX3d cmf(const WavelengthGrid& grid, Observer observer) {
  const CieTable table = cmf_table(observer);
  Eigen::MatrixX3d out(Eigen::Index(grid.size()), 3);
  for (int c = 0; c < 3; ++c) out.col(c) = sample_tabulated(table.nm, table.columns[std::size_t(c)], grid);
  return out;
}

Eigen::VectorXd illuminant(std::string_view name, const WavelengthGrid& grid) {
  if (name == "E") return Eigen::VectorXd::Constant(Eigen::Index(grid.size()), 100.0);
  if (name == "D65" || name == "D50" || name == "A") {
    const CieTable table = illuminant_table(name);
    return sample_tabulated(table.nm, table.columns[0], grid);
  }
  throw UsageError("unknown illuminant \"" + std::string(name) + "\"; use one of D65, D50, A, E");
}

Eigen::VectorXd daylight(double cct_kelvin, const WavelengthGrid& grid) {
  if (!(cct_kelvin >= 4000.0 && cct_kelvin <= 25000.0))
    throw UsageError("daylight CCT " + num(cct_kelvin) + " K is outside the CIE daylight locus; choose 4000-25000 K");
  // CIE 15:2004: chromaticity on the daylight locus, then the basis weights M1, M2
  // rounded to three decimals as the CIE prescribes.
  const double t = cct_kelvin;
  const double x = t <= 7000.0 ? -4.6070e9 / (t * t * t) + 2.9678e6 / (t * t) + 0.09911e3 / t + 0.244063
                               : -2.0064e9 / (t * t * t) + 1.9018e6 / (t * t) + 0.24748e3 / t + 0.237040;
  const double y = -3.000 * x * x + 2.870 * x - 0.275;
  const double m = 0.0241 + 0.2562 * x - 0.7341 * y;
  const double m1 = std::round(1000.0 * (-1.3515 - 1.7703 * x + 5.9114 * y) / m) / 1000.0;
  const double m2 = std::round(1000.0 * (0.0300 - 31.4424 * x + 30.0717 * y) / m) / 1000.0;

  const CieTable basis = daylight_basis_table();
  std::vector<double> spd(basis.nm.size());
  for (std::size_t i = 0; i < spd.size(); ++i)
    spd[i] = basis.columns[0][i] + m1 * basis.columns[1][i] + m2 * basis.columns[2][i];
  const double at560 = sample_tabulated(basis.nm, spd, WavelengthGrid({560.0}))[0];
  return sample_tabulated(basis.nm, spd, grid) * (100.0 / at560);
}

Eigen::VectorXd blackbody(double kelvin, const WavelengthGrid& grid) {
  if (!(kelvin > 0.0) || !std::isfinite(kelvin))
    throw UsageError("blackbody temperature " + num(kelvin) + " K is invalid; give a finite temperature above 0 K");
  // Second radiation constant c2 = h c / k (exact SI values), in nm K.
  const double c2 = 6.62607015e-34 * 299792458.0 / 1.380649e-23 * 1e9;
  const double ref = 560.0;
  const double log_ref = log_expm1(c2 / (ref * kelvin));
  Eigen::VectorXd out(Eigen::Index(grid.size()));
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const double nm = grid[i];
    out[Eigen::Index(i)] = std::exp(5.0 * std::log(ref / nm) + log_ref - log_expm1(c2 / (nm * kelvin)));
  }
  return out;
}

}  // namespace specula
