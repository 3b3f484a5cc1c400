#include "specula/acquire/retro_band.h"

#include <algorithm>

#include "specula/core/brdf_geometry.h"

namespace specula::acquire {

int unseen_retro_rows(std::span<const std::uint32_t> observed) {
  int rows = brdf::kMerlThetaD;
  const auto& cells = valid_cells();
  for (const std::uint32_t v : observed) rows = std::min(rows, brdf::merl_cell(std::size_t(cells[v])).theta_d);
  return rows;
}

bool in_unseen_retro(int rows, std::size_t cell) { return brdf::merl_cell(cell).theta_d < rows; }

}  // namespace specula::acquire
