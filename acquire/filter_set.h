#pragma once
// A set of broadband filters (acquire/filters.h models them): transmission curves on one wavelength tabulation.
#include <cstddef>
#include <string>
#include <vector>

namespace specula::acquire {

/// K transmission curves tabulated on one wavelength grid; linear between the points, zero outside them.
struct FilterSet {
  std::vector<std::string> names;
  std::vector<double> nm;                         ///< increasing
  std::vector<std::vector<double>> transmission;  ///< K curves, each nm.size() values in [0, 1]
  std::size_t size() const { return transmission.size(); }
  /// Transmission of filter k at l (0 outside the tabulation).
  double at(std::size_t k, double l) const;
};

}  // namespace specula::acquire
