#pragma once
// Inside store/ only: the optional `parameterisation` group of a BRDF grid (docs/store-format.md).
#include <hdf5.h>

#include <optional>
#include <string>

#include "specula/store/grid.h"

namespace specula::store {

/// What is wrong with `p` (sizes that disagree, fewer than 2 nodes, not isotropic), or empty.
std::string parameterisation_problem(const GridParameterisation& p);
/// Writes `p` as the group `parameterisation` of the open grid group; UsageError (naming ctx) when it is malformed.
void write_parameterisation(hid_t grid, const GridParameterisation& p, const std::string& ctx);
/// The group `parameterisation` of the open grid group, or nullopt when absent (stores written before it); InputError
/// naming ctx for a newer version, another kind or malformed arrays.
std::optional<GridParameterisation> read_parameterisation(hid_t grid, const std::string& ctx);

}  // namespace specula::store
