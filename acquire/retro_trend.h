#pragma once
// The material's trend into the unseen retro-reflection band (acquire/retro_band.h continues it; docs/prior.md): in
// each (theta_h, phi_d) column a least-squares line of ln v against x = theta_d^p, theta_d each row's centre. p = 2
// is a BRDF smooth at retro-reflection (reciprocity makes it even in theta_d there), p = 1 one with a cusp; a prior
// learns p from its training grids (build_prior, acquire/prior.h), per width of the band.
#include <cstddef>
#include <span>
#include <vector>

namespace specula::acquire {

/// A line in x: mean + slope (x - x_mean).
struct TrendLine {
  double x_mean = 0, mean = 0, slope = 0;
  double at(double x) const { return mean + slope * (x - x_mean); }
};

/// The least-squares line through (x[i], y[i]) (same sizes), its slope s shrunk to s max(0, 1 - se^2 / s^2) (se its
/// standard error; more than 2 points): a trend lost in the noise stays flat.
TrendLine shrunk_line(std::span<const double> x, std::span<const double> y);

/// The centre of MERL theta_d row r in degrees: r + 0.5.
constexpr double retro_row_centre(int r) { return r + 0.5; }

/// The abscissa of theta_d row r: retro_row_centre(r) to the power `exponent`.
double retro_abscissa(int r, double exponent);

/// The exponent of a band of `rows` theta_d rows in the table `exponents` (one per width 1, 2, ...; wider bands take
/// the last): 2 when the table is empty (a prior written before it was learned).
double retro_exponent(std::span<const double> exponents, int rows);

/// The widest band (theta_d rows) a prior learns its own exponent for.
inline constexpr int kRetroLearnedRows = 8;
/// The exponents a prior chooses among: 1, 1.1, ..., 2.
std::span<const double> retro_exponent_candidates();

/// Sums, over grids added row by row, each candidate exponent's squared ln error when a band of B rows is continued
/// from the B rows above it, for B = 1 .. kRetroLearnedRows.
class RetroExponentTally {
 public:
  RetroExponentTally();
  /// Adds theta_h rows [h0, h0 + rows) of one grid: values (channels x rows x kMerlThetaD x kMerlPhiD, > 0 where
  /// there is data). A (theta_h, phi_d) column counts for width B when theta_h row >= 10 (the peak's cap, where the
  /// scan's cap rule decides, left out) and its rows [0, 2B) hold valid cells with values > 0 in every channel.
  /// UsageError on sizes or rows.
  void add(std::span<const float> values, std::size_t channels, std::size_t h0, std::size_t rows);
  /// Per width B = 1 .. kRetroLearnedRows the candidate of least summed error (the larger on a tie; 2 where no column
  /// counted).
  std::vector<double> exponents() const;
  /// The mean squared ln error of candidate c at width B (0 where no column counted).
  double mean_error(int width, std::size_t candidate) const;

 private:
  std::vector<double> error_;  // kRetroLearnedRows x candidates
  std::vector<double> count_;  // kRetroLearnedRows: band cells summed
};

}  // namespace specula::acquire
