#pragma once
// The rise of the unseen retro-reflection band learned from its shoulder (docs/prior.md, "The band's rise learned
// from its shoulder"): how a material's BRDF climbs into retro-reflection over the theta_d rows a rig never sees
// (acquire/retro_band.h) is told, across the training materials, by how it climbs over the rows above them that the
// rig does see. A prior learns a ridge map per band width from the training grids' profiles (the level of each theta_d
// row, summed over bands, theta_h and phi_d) of the shoulder to those of the band; a resample scales the band's rows
// so that the result's profile there is the one its own shoulder predicts. Only from kRetroRiseFromThetaH on, where
// the band of a fabric rises well above what a continuation reaches.
#include <cstddef>
#include <span>
#include <vector>

#include "specula/acquire/retro_trend.h"

namespace specula::acquire {

/// The first theta_h row (22.5 degrees) whose band the rise map learns and corrects.
inline constexpr int kRetroRiseFromThetaH = 45;
/// The ridge weight of the maps (on the intercept too): profiles are ln ratios of order 0.1.
inline constexpr double kRetroRiseLambda = 1e-4;

/// The values in a table of maps of widths 1 .. widths: width w's is 2w x w.
std::size_t retro_rise_size(int widths = kRetroLearnedRows);
/// Width w's map in table `maps` (2w x w, row-major; rows: the intercept, then profile rows w + 1 .. 3w - 1; columns:
/// profile rows 0 .. w - 1); empty when w < 1 or the table holds no map that wide. UsageError when the table's size
/// is no retro_rise_size.
std::span<const double> retro_rise_map(std::span<const double> maps, int width);

/// The profile of a band `width` theta_d rows wide in grid (bands x kMerlCells): per theta_d row r in [0, 3 width),
/// ln of the sum of max(v, 0) over bands, theta_h rows [kRetroRiseFromThetaH, 90) and the phi_d columns whose rows
/// [0, 3 width) are all valid cells, less that of row `width`; empty when some row's sum is not > 0. UsageError on
/// sizes or a width outside [1, 30].
std::vector<double> retro_profile(std::span<const float> grid, std::size_t bands, int width);

/// Sums, over grids added theta_h row by row, each grid's profile sums for widths 1 .. kRetroLearnedRows, and fits
/// the maps.
class RetroRiseTally {
 public:
  explicit RetroRiseTally(std::size_t grids);
  /// Adds theta_h rows [from, h0 + rows) of grid g (those before `from` were added with an earlier block) from values
  /// holding rows [h0, h0 + rows): bands x rows x kMerlThetaD x kMerlPhiD, each times scale. UsageError on sizes,
  /// rows or g.
  void add(std::size_t g, std::span<const float> values, std::size_t bands, std::size_t h0, std::size_t rows,
           std::size_t from, double scale);
  /// The table of maps (retro_rise_size() values): per width the ridge regression (kRetroRiseLambda) of the band's
  /// profile rows on the intercept and the shoulder's, over the grids whose profile is complete (none: a map of
  /// zeros, which flattens the band to row w's level).
  std::vector<double> maps() const;

 private:
  std::size_t grids_;
  std::vector<double> sums_;  // grids x (3 + 6 + ... + 3 kRetroLearnedRows): per width, per theta_d row
};

/// Scales theta_d rows [0, rows) of grid (bands x kMerlCells) at theta_h rows [kRetroRiseFromThetaH, 90), every band
/// and valid cell of row r by exp(predicted[r] - profile[r]), predicted from the grid's own shoulder by the map of
/// width `rows` in `maps` (retro_rise_map). Returns those factors; empty (grid untouched) when rows is 0, the table
/// holds no map that wide or the grid's profile is incomplete. UsageError on sizes or rows < 0.
std::vector<double> raise_retro_band(std::span<float> grid, std::size_t bands, std::span<const double> maps, int rows);

}  // namespace specula::acquire
