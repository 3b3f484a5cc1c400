#pragma once
// Exporting a grid to a perceptual target: the smallest RGL file (codec/rgl_export.h) on a fixed ladder of
// resolutions whose import the lighting suite (codec/suite.h) cannot tell from the grid beyond the target. For
// materials the default 8 theta_i x 32^2 cannot hold (the real orange vinyl, docs/brdf.md), as `encode
// --target-de00` chooses its coding.
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "specula/codec/rgl_export.h"
#include "specula/codec/suite.h"

namespace specula::codec {

/// The (theta_i, resolution) pairs export_rgl_to_target tries, smallest file first: incident elevations before
/// sample nodes, which gain more per byte on the materials of docs/benchmarks.md.
inline constexpr std::array<std::pair<std::size_t, std::size_t>, 8> kRglTargetLadder{
    {{8, 32}, {12, 32}, {16, 32}, {24, 32}, {32, 32}, {24, 48}, {32, 48}, {32, 64}}};

/// export_rgl, except under `automatic` for a grid whose source parameterisation rgl_parameterisation_used picks:
/// then both it and the estimated one are exported and the file whose import (rgl_to_grid) `suite` finds closer to
/// the grid (pooled ΔE00 mean) is returned; the source's tables are not always the better (docs/brdf.md, Export).
/// `used` says which was returned. With `rgb` (grid_to_merl's weights), the RGB file of grid_to_merl(grid, *rgb) on
/// the parameterisation the spectral files so judged pick. UsageError as export_rgl.
RglBsdf export_rgl_judged(const store::Grid& grid, const RglExportSettings& settings, const LightingSuite& suite,
                          RglParameterisation& used, const Eigen::Matrix<double, 3, Eigen::Dynamic>* rgb = nullptr);

/// What a target asks: the suite's pooled ΔE00 mean and 95th percentile of the grid against the file's import.
struct RglTarget {
  double de00_mean = 0.5;
  double de00_p95 = 1.5;
};

/// One resolution tried.
struct RglTargetTrial {
  std::size_t theta_i = 0, resolution = 0;
  RglParameterisation parameterisation = RglParameterisation::estimate;  ///< source or estimate
  std::uint64_t bytes = 0;
  double de00_mean = 0, de00_p95 = 0;
  bool met = false;
};

/// Where the search ended: reached false when no resolution of the ladder met the target (the largest is returned).
struct RglTargetReport {
  bool reached = false;
  std::vector<RglTargetTrial> trials;
};

/// The export of `grid` (export_rgl with `settings`) meeting `target` under `suite` (its import, rgl_to_grid): first on
/// the grid's source parameterisation when rgl_parameterisation_used picks it, then (unless settings ask `source`)
/// estimated at each ladder entry from the first not smaller than settings' own size (0:
/// 8 theta_i, 32^2), stopping at the first that meets it; the trials go into `report`. UsageError for a target that is
/// not positive, a grid off the suite's wavelengths, or `source` asked of a grid without one.
RglBsdf export_rgl_to_target(const store::Grid& grid, const RglExportSettings& settings, const RglTarget& target,
                             const LightingSuite& suite, RglTargetReport& report);

}  // namespace specula::codec
