#pragma once
// A two-band MERL grid whose phi_d rings are ln v = A(k, theta_h, theta_d) + D(k, theta_h, theta_d) cos 2 phi_d at the
// column centres, -1 below the horizon: the closed form the pole's and the peak's settling tests check against.
#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

#include "specula/core/brdf_geometry.h"

namespace specula::test {

/// cos 2 phi_d at the centre of phi_d column p.
inline double cos2_phi_d(int p) { return std::cos(2 * (p + 0.5) * std::numbers::pi / 180); }

/// The grid above (2 x kMerlCells) for level A and amplitude D, both called as f(band, theta_h row, theta_d row).
template <class Level, class Amplitude>
std::vector<float> cos2_phi_d_grid(const Level& A, const Amplitude& D) {
  std::vector<float> grid(2 * brdf::kMerlCells, -1.0f);
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const brdf::MerlCell m = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(m)) continue;
    for (std::size_t k = 0; k < 2; ++k)
      grid[k * brdf::kMerlCells + cell] =
          float(std::exp(A(k, m.theta_h, m.theta_d) + D(k, m.theta_h, m.theta_d) * cos2_phi_d(m.phi_d)));
  }
  return grid;
}

}  // namespace specula::test
