#pragma once
// Wavelength grids (nm) and linear resampling between them.
#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula {

/// A strictly increasing list of finite, positive wavelengths in nanometres.
class WavelengthGrid {
 public:
  WavelengthGrid() = default;
  /// Takes wavelengths in nm; throws InputError (prefixed by `context`) unless finite, positive and strictly
  /// increasing.
  explicit WavelengthGrid(std::vector<double> nm, std::string_view context = "wavelengths");
  /// Grid first, first+step, ... up to last inclusive (within step/1000); throws UsageError on a bad range.
  static WavelengthGrid range(double first, double last, double step);
  /// Parses "420:720:10" (first:last:step) or a comma list "450,550,650"; throws UsageError with the rule.
  static WavelengthGrid parse(std::string_view spec);

  std::size_t size() const { return nm_.size(); }
  bool empty() const { return nm_.empty(); }
  double operator[](std::size_t i) const { return nm_[i]; }
  double front() const { return nm_.front(); }
  double back() const { return nm_.back(); }
  std::span<const double> values() const { return nm_; }
  /// True when both grids have the same size and every wavelength agrees within tol_nm.
  bool approx_equal(const WavelengthGrid& other, double tol_nm = 1e-6) const;
  /// True when the spacing is constant (within 1e-6 nm); step() is then meaningful.
  bool uniform() const;
  /// Spacing of a uniform grid (0 for fewer than two bands).
  double step() const;
  /// Index of the band nearest `nm` (the lower one of two as near); 0 for an empty grid.
  std::size_t nearest(double nm) const;
  /// Short description, e.g. "31 bands 420-720 nm step 10" or "3 bands 450-650 nm (irregular)".
  std::string describe() const;

 private:
  std::vector<double> nm_;
};

/// `bands` (indices into `nm`) in ascending order of their wavelengths: a list given unsorted is kept exactly,
/// permuted, never resampled. For a wavelength listed twice calls `repeated(first, second)` (indices, first < second),
/// which throws the caller's InputError naming the file; LibraryError if it returns.
std::vector<std::size_t> ascending_band_order(std::span<const double> nm, std::vector<std::size_t> bands,
                                              const std::function<void(std::size_t, std::size_t)>& repeated);
/// ascending_band_order of every band 0..nm.size()-1.
std::vector<std::size_t> ascending_band_order(std::span<const double> nm,
                                              const std::function<void(std::size_t, std::size_t)>& repeated);

/// Linear-interpolation matrix R (to.size() x from.size()) so that R * s resamples s; throws InputError
/// naming the first wavelength of `to` outside [from.front(), from.back()] (no extrapolation).
Eigen::MatrixXd resample_matrix(const WavelengthGrid& from, const WavelengthGrid& to,
                                std::string_view context = "resampling");

/// Samples the piecewise-linear function (x, y) at `grid`; zero outside [x.front(), x.back()] (for CMFs and SPDs).
Eigen::VectorXd sample_tabulated(std::span<const double> x, std::span<const double> y, const WavelengthGrid& grid);

/// Trapezoid-rule quadrature weights for integrating a function sampled on `grid`.
Eigen::VectorXd trapezoid_weights(const WavelengthGrid& grid);

}  // namespace specula
