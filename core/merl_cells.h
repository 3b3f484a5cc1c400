#pragma once
// The cells of the MERL grid with both directions above the horizon, listed once for every user.

#include <cstdint>
#include <vector>

namespace specula::brdf {

/// The linear indices of every cell merl_cell_valid holds for, ascending; listed once per process, on all threads.
const std::vector<std::uint32_t>& merl_valid_cells();

}  // namespace specula::brdf
