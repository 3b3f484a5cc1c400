#pragma once
// The rows round the specular peak, between the unseen cap (acquire/peak_cap.h) and theta_h row `rows` (docs/prior.md,
// "The peak's rows settled"). A rig samples them sparsely (at 165 lights about one cell in forty holds a sample) and
// the kd-tree's neighbours reach across a steep lobe, so the estimate scatters over phi_d where the BRDF hardly
// varies: at theta_h = 0 every phi_d names the same pair of directions up to a turn about the normal, and
// reciprocity leaves an isotropic BRDF even in phi_d there, so it departs from its ring's mean as sin^2 theta_h.
#include <cstddef>
#include <span>
#include <vector>

#include "specula/acquire/peak_cap.h"

namespace specula::acquire {

/// The most theta_h rows round the peak that `resample --prior` settles (rows below 20, theta_h < 4.7 degrees); the
/// scan chooses how many of them (`PriorMethod::peak_auto`, acquire/peak_rows_choice.h) unless `PriorMethod::peak_rows`
/// sets it.
inline constexpr int kPeakRows = 20;

/// In every band and theta_d row d, for theta_h rows h in [cap[d], keep.size()) with keep[h] < 1, each cell with a
/// value > 0 has ln v drawn towards the mean of ln v over its phi_d ring's cells > 0, keeping the share keep[h] of its
/// departure. Cells <= 0, below the horizon or in the cap are left. Returns the cells settled (those > 0 in some band).
/// UsageError on sizes, more than kMerlThetaH rows or a keep outside [0, 1].
std::size_t settle_peak_rows(std::span<float> grid, std::size_t bands, const UnseenCap& cap,
                             std::span<const double> keep);

/// The keeps of `--peak-rows N`: row h below `rows` keeps sin^2(theta_h) / sin^2(theta_h of row `rows`) of its
/// departure (row centres), the rule for rows given rather than chosen. UsageError for rows outside [0, kMerlThetaH).
std::vector<double> sin2_keeps(int rows);

}  // namespace specula::acquire
