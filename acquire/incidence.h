#pragma once
// The samples of a stored set that lie near an incidence plane (figures 5.5-5.7, 5.17): what `specula acquire
// --plot` draws and the viewer plots, read once from the store.
#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "specula/store/store.h"

namespace specula::acquire {

/// One sample near an incidence plane: its signed outgoing angle (radians, incidence_plane_angle) and its value at
/// the band asked for.
struct PlanePoint {
  double theta_o = 0;
  float value = 0;
};

/// Points of one incidence plane and how many samples were read to find them.
struct PlanePoints {
  std::vector<PlanePoint> points;
  std::size_t scanned = 0;
};

/// For each theta_i (radians), the samples of `name` within eps of its incidence plane, in stored order, valued at
/// `band` (UsageError past the last band). Streams the set in blocks of max(chunk rows, 65536), reading a block's
/// values only when one of its samples lies in a plane, and stops after the block in which every plane has `limit`
/// points (each plane keeps at most `limit`); `scanned` counts the samples read.
std::vector<PlanePoints> incidence_plane_points(const store::Store& s, const std::string& name,
                                                std::span<const double> theta_i, double eps, std::size_t band,
                                                std::size_t limit = std::numeric_limits<std::size_t>::max());

}  // namespace specula::acquire
