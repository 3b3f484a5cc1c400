#include "specula/codec/grid_slice.h"

#include <cmath>
#include <limits>
#include <numbers>

#include "specula/core/brdf_geometry.h"

namespace specula::codec {

GridSlice incidence_slice(const store::Grid& grid, double theta_i) {
  using std::numbers::pi;
  GridSlice s;
  s.bands = grid.bands();
  for (int deg = -89; deg <= 89; ++deg) {
    const double to = std::abs(deg) * pi / 180;
    const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::StdAngles{theta_i, 0.0, to, deg > 0 ? pi : 0.0}));
    s.theta_o_deg.push_back(deg);
    for (std::size_t b = 0; b < s.bands; ++b) {
      const float v = grid.brdf[b * brdf::kMerlCells + cell];
      s.values.push_back(v < 0 ? std::numeric_limits<double>::quiet_NaN() : double(v) * grid.scale);
    }
  }
  return s;
}

}  // namespace specula::codec
