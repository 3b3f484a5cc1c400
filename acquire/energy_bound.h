#pragma once
// Energy conservation as a bound on a fitted BRDF (docs/prior.md, "The energy bound"): where no sample constrains
// it, a prior's fit can run away (up to 10^4 times the truth at grazing cells of a paint, 10 lights), and the
// directional albedo rho(theta_i) = integral of f(wi, wo) cos theta_o d wo, at most 1 for a passive material, is
// where that shows: the runaway's albedo reaches 86 while real materials stay near or below 1 (the NBRDF materials
// up to 1.51 at grazing, RGL's up to 2.1 for a saturated orange uplifted past 1). The albedo is integrated over the
// half vector, where the MERL grid resolves a peak (d wo = 4 (wi . h) d wh), on theta_h rows split like the grid's, so
// a peak of a few cells counts in full.
#include <cstddef>
#include <span>

namespace specula::acquire {

/// Incidence rows of the albedo: theta_i = (r + 1/2) degrees, r < kAlbedoRows.
inline constexpr std::size_t kAlbedoRows = 90;

/// The bound rho_k(theta_i) <= max(floor, kappa m_k) per band k, m_k the median over theta_i below 60 degrees of the
/// grid's own albedo. A passive material in 1/sr stays below 1, but measured ones reach 1.51 at grazing (MERL's
/// pink-plastic), so the floor leaves room above them; kappa m_k covers values in another scale or a material that
/// seems brighter (fluorescence, an uplift past 1).
struct EnergyBoundOptions {
  double floor = 2;  ///< > 0
  double kappa = 2;  ///< > 0
};

/// The directional albedo of grid (bands x kMerlCells, 1/sr; a cell without data, below 0 in band 0, counts 0) at
/// each incidence row, per band, into out (kAlbedoRows x bands, row-major). UsageError on sizes.
void directional_albedo(std::span<const float> grid, std::size_t bands, std::span<double> out);

/// Scales the spectrum of every cell whose values push its incidence rows' albedo above the bound down, each by one
/// factor (its colour kept), the brightest cells first: per row the cells brighter than a threshold are cut to it,
/// the threshold set so the row meets the bound; a cell in several rows takes its smallest factor. Returns the cells
/// scaled. UsageError on sizes, floor or kappa.
std::size_t bound_energy(std::span<float> grid, std::size_t bands, const EnergyBoundOptions& o);

}  // namespace specula::acquire
