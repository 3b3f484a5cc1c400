#pragma once
// The cap round the specular peak that a rig never samples (docs/prior.md, "The unseen peak"): on the MERL grid the
// theta_h rows crowd towards theta_h = 0 (row i starts at (i / 90)^2 90 degrees), and a sphere imaged with a finite
// number of pixels and lights leaves the lowest rows without a single sample (the reference's rig: theta_h below
// about 0.3 degrees, rows 0-4). A glossy material keeps its highest values there; the kd-tree's estimate from the
// nearest samples, all farther out on the lobe, flattens them, so the prior, which learned how peaks continue from
// its training materials, is used there instead.
#include <array>
#include <cstddef>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_geometry.h"

namespace specula::acquire {

/// Per theta_d index, the number of theta_h rows below the lowest row holding an observed cell in the theta_d rows
/// within 8 of it (kMerlThetaH when none does).
using UnseenCap = std::array<int, brdf::kMerlThetaD>;

/// The unseen cap of observations obs (cells index valid_cells()).
UnseenCap unseen_cap(const PriorObservations& obs);

/// True when MERL cell `cell` (linear index) lies in the cap: its theta_h row is below the first observed one of its
/// theta_d row.
bool in_unseen_cap(const UnseenCap& cap, std::size_t cell);

}  // namespace specula::acquire
