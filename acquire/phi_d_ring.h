#pragma once
// The phi_d rings of the MERL grid (one theta_h row and theta_d row: kMerlPhiD cells) drawn towards their own mean.
// Where the pair of directions hardly depends on phi_d (at theta_d = 0, the retro-reflection pole, and at theta_h = 0,
// the specular peak) an isotropic BRDF, even in the difference vector by reciprocity, departs from its ring's mean
// only at second order (sin^2 of the angle): acquire/retro_band.h and acquire/peak_rows.h settle the estimates there.
#include <cstddef>
#include <span>

namespace specula::acquire {

/// In every band of grid (bands x kMerlCells), the ring starting at MERL cell `first` (phi_d 0 of its theta_h and
/// theta_d rows): its values > 0 have ln v drawn towards their mean of ln v, keeping the share `keep` of each
/// departure (0: all at the geometric mean; 1: unchanged); values <= 0 are left. Returns the ring's cells > 0 in some
/// band.
std::size_t settle_phi_d_rings(std::span<float> grid, std::size_t bands, std::size_t first, double keep);

/// The share of its departure a cell at angle a keeps when the ring at angle b keeps all of it: sin^2 a / sin^2 b
/// (radians; b not a multiple of pi).
double sin2_share(double a, double b);

}  // namespace specula::acquire
