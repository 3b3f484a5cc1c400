#pragma once
// The band round retro-reflection that a rig never samples (docs/prior.md, "The unseen retro-reflection band"): a
// light cannot stand where the camera is, so with the reference's rig (lights from 10 degrees off the camera) no
// sample has theta_d below 5 degrees. A prior's fit is unconstrained there and extrapolates from its training
// materials; the kd-tree's estimate continues the material's own samples from the band's edge. Which is closer
// depends on the material (a black glass: the continuation; a fabric's retro-reflection: the prior), so the band's
// weight of the kd-tree is chosen from the scan (acquire/prior_reach.h), by the same extrapolation one band higher.
#include <cstddef>
#include <cstdint>
#include <span>

#include "specula/acquire/prior.h"

namespace specula::acquire {

/// The number of theta_d rows below the lowest theta_d row holding one of the observed cells (positions in
/// valid_cells()); kMerlThetaD when there are none.
int unseen_retro_rows(std::span<const std::uint32_t> observed);
/// unseen_retro_rows of the cells of observations obs.
inline int unseen_retro_rows(const PriorObservations& obs) { return unseen_retro_rows(obs.cell); }

/// True when MERL cell `cell` (linear index) lies in the band: its theta_d row is below `rows`.
bool in_unseen_retro(int rows, std::size_t cell);

/// The material's own trend continued down in theta_d: for every valid (theta_h, phi_d) column of grid (bands x
/// kMerlCells), each band's shrunk_line (acquire/retro_trend.h) of ln v against retro_abscissa(row, exponent) through
/// the column's values at theta_d rows [first + count, first + 2 count), evaluated at rows [first, first + count) and
/// written into out at those rows' valid cells (bands x kMerlCells; nothing else written, so out may be grid itself).
/// A column with a value <= 0 (or no data) among its known rows, or whose rows leave the grid, is left as it is.
/// UsageError on sizes, rows or an exponent <= 0.
void continue_retro(std::span<const float> grid, std::size_t bands, int first, int count, double exponent,
                    std::span<float> out);

/// Reciprocity at the pole: at theta_d = 0 every phi_d names the same pair of directions, and a BRDF even in the
/// difference vector leaves it as sin^2 theta_d. In every band and theta_h row of theta_d rows [0, rows), each cell
/// with a value > 0 has ln v drawn towards the mean of ln v over the row's cells > 0, keeping the share
/// sin^2(theta_d) / sin^2(theta_d of row `rows`) of its departure (row centres). Cells <= 0 or below the horizon are
/// left. Returns the cells settled (those > 0 in some band). UsageError on sizes or rows outside [0, kMerlThetaD).
std::size_t settle_retro_pole(std::span<float> grid, std::size_t bands, int rows);

}  // namespace specula::acquire
