#pragma once
// A spectral BRDF grid read along an incidence plane (figures 5.5-5.7): what the viewer plots for a grid.
#include <cstddef>
#include <vector>

#include "specula/store/grid.h"

namespace specula::codec {

/// The grid along the incidence plane at theta_i: theta_o_deg from -89 to 89 degrees in steps of 1 (negative: the
/// viewer on the light's side, phi_d = 0; positive: towards the mirror direction, phi_d = pi), and per angle the
/// grid's bands at the cell merl_cell gives (value times scale, 1/sr), row-major (angle, band); NaN where the cell
/// has no data.
struct GridSlice {
  std::vector<int> theta_o_deg;
  std::size_t bands = 0;
  std::vector<double> values;
};

/// The incidence-plane slice of `grid` at theta_i (radians).
GridSlice incidence_slice(const store::Grid& grid, double theta_i);

}  // namespace specula::codec
