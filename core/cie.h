#pragma once
// CIE standard data (published standard values, embedded): colour-matching functions, illuminants,
// the daylight basis. Everything is returned resampled to a caller's WavelengthGrid.
#include <Eigen/Core>
#include <span>
#include <string_view>
#include <vector>

#include "specula/core/wavelengths.h"

namespace specula {

enum class Observer { cie1931_2deg, cie1964_10deg };

/// A tabulated standard function: wavelengths (nm) and one or more value columns of equal length.
struct CieTable {
  std::span<const double> nm;
  std::vector<std::span<const double>> columns;
};

/// The embedded 1 nm CMF table (360-830 nm), columns xbar, ybar, zbar.
CieTable cmf_table(Observer observer);
/// The embedded SPD table of "A", "D50" or "D65" (300-780 nm, 5 nm); throws UsageError for other names.
CieTable illuminant_table(std::string_view name);
/// The embedded daylight basis table, columns S0, S1, S2.
CieTable daylight_basis_table();

/// CMFs sampled at `grid` (columns xbar, ybar, zbar), linear interpolation, zero outside the table.
Eigen::MatrixX3d cmf(const WavelengthGrid& grid, Observer observer = Observer::cie1931_2deg);
/// Relative SPD of "D65", "D50", "A" or "E" (equal energy) at `grid`; throws UsageError naming the known names.
Eigen::VectorXd illuminant(std::string_view name, const WavelengthGrid& grid);
/// CIE daylight of correlated colour temperature cct (4000-25000 K, else UsageError) from S0 + M1 S1 + M2 S2, 100 at
/// 560 nm.
Eigen::VectorXd daylight(double cct_kelvin, const WavelengthGrid& grid);
/// Planck's law at temperature kelvin, normalised to 1 at 560 nm.
Eigen::VectorXd blackbody(double kelvin, const WavelengthGrid& grid);

}  // namespace specula
