#pragma once
// How `resample --prior` treats the theta_h rows round the peak (acquire/peak_rows.h), chosen from the scan
// (docs/prior.md, "The peak's rows chosen from the scan"). Settling assumes the kd-tree's estimate departs over phi_d
// by more than the BRDF does: its neighbours reach across a steep lobe and scatter. A measurement can vary over phi_d
// itself (grease-covered-steel's truth, by a factor two at theta_h = 0), and then settling loses. The samples tell:
// in a phi_d ring two samples at nearly the same theta_h and theta_d differ in ln f by noise and the cell's slope
// when they are near in phi_d, and also by the ring's own dependence on phi_d when they are far apart; the RMS excess
// of the far pairs over the near ones is the samples' spread over phi_d. The grid's spread is the RMS difference of
// ln f between its cells far apart on the same rings. A group of rows keeps the share (samples' / grid's spread)^2 of
// its departure over phi_d, at most all of it: the part of the grid's variance the BRDF's own accounts for.
#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <span>
#include <vector>

#include "specula/core/brdf_resample.h"

namespace specula::acquire {

struct PeakRowsChoiceOptions {
  int group = 5;                      ///< theta_h rows judged together, from row 0 up to kPeakRows
  double theta_h_tolerance = 0.05;    ///< a pair's theta_h differ by at most this fraction of the larger
  double theta_d_tolerance = 0.0052;  ///< a pair's theta_d differ by at most this (radians; 0.3 degrees)
  double near = 0.26;                 ///< a near pair's phi_d differ by less than this (radians, mod pi; 15 degrees)
  double far = 1.05;                  ///< a far pair's phi_d differ by more than this (radians, mod pi; 60 degrees)
  std::size_t ring_samples = 300;     ///< at most this many samples of a ring are paired (evenly spaced in order)
  std::size_t min_pairs = 50;         ///< a group with fewer near or far pairs is not measured
};

/// What the samples say of one group of theta_h rows.
struct PeakRowsGroup {
  int first_row = 0;
  std::size_t near_pairs = 0, far_pairs = 0;
  double near_rms = 0, far_rms = 0;  ///< RMS difference of ln f over the near and the far pairs
  double spread = 0;                 ///< sqrt(max(0, far_rms^2 - near_rms^2)); 0 when not measured
  double grid_spread = 0;            ///< RMS ln difference of the grid's cells > 0 far apart on the paired rings
  bool measured = false;             ///< both kinds of pairs at least min_pairs
  double keep = 1;                   ///< share of each cell's departure over phi_d kept by settle_peak_rows
};

struct PeakRowsChoice {
  int rows = 0;  ///< the log residuals average over phi_d rings in theta_h rows below this (0: none)
  std::vector<PeakRowsGroup> groups;
  std::size_t samples = 0;  ///< samples in the groups' rows with a mean value > 0
  double seconds = 0;
};

/// Measures the groups of `grid` (bands x kMerlCells, the estimate before settling) as the header says. A group
/// measured keeps min(1, (spread / grid_spread)^2); those below the first measured keep its share, those above it
/// unmeasured 1. `rows`: from the first group measured on, the groups measured with a grid spread above the samples',
/// ending at the first that is not. ln f is that of the mean over bands, of a sample or a cell. The same for any
/// thread count. UsageError for bad options or sizes.
PeakRowsChoice choose_peak_rows(const brdf::SampleSource& src, std::span<const float> grid, std::size_t bands,
                                const PeakRowsChoiceOptions& o);

/// Per theta_h row below kPeakRows, the keep of the group holding it (groups in first_row order; 1 with none).
std::vector<double> row_keeps(const PeakRowsChoice& c);

/// The choice, as `resample --json` reports it under "peak_rows_auto".
nlohmann::ordered_json peak_rows_choice_json(const PeakRowsChoice& c);

}  // namespace specula::acquire
