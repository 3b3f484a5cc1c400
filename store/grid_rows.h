#pragma once
// Part of a store's BRDF grid: whole theta_h rows, reading only the chunks that hold them (what a prior's streamed
// training reads, acquire/prior.h).
#include <cstddef>
#include <span>
#include <string>

namespace specula::store {

class Store;

/// theta_h rows [theta_h0, theta_h0 + rows) of grid `name` of s into out (bands x rows x 90 x 180, unscaled values).
/// InputError when the grid is absent or malformed; UsageError for rows beyond 90 or a wrong size.
void read_grid_rows(const Store& s, const std::string& name, std::size_t theta_h0, std::size_t rows,
                    std::span<float> out);

}  // namespace specula::store
