#pragma once
// A phi_d ring of the MERL grid (one band, theta_h row and theta_d row: kMerlPhiD cells) drawn towards its own mean.
// Where the pair of directions hardly depends on phi_d (at theta_d = 0, the retro-reflection pole, and at theta_h = 0,
// the specular peak) an isotropic BRDF, even in the difference vector by reciprocity, departs from its ring's mean
// only at second order (sin^2 of the angle): acquire/retro_band.h and acquire/peak_rows.h settle the estimates there.
#include <span>

namespace specula::acquire {

/// The values > 0 of `ring` have ln v drawn towards their mean of ln v, keeping the share `keep` of each departure
/// (0: all at the geometric mean; 1: unchanged); values <= 0 are left. Returns the number of values > 0.
int settle_phi_d_ring(std::span<float> ring, double keep);

/// The share of its departure a cell at angle a keeps when the ring at angle b keeps all of it: sin^2 a / sin^2 b
/// (radians; b not a multiple of pi).
double sin2_share(double a, double b);

}  // namespace specula::acquire
