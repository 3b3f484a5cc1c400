#pragma once
// The tables of a learned BRDF prior (acquire/prior.h) as the store keeps them: the "priors" object kind
// (docs/store-format.md). Written by StoreWriter::add_prior (its components in memory or made block by block as
// they are written), read by Store::read_prior (the components whole, or not at all) and
// Store::read_prior_components (a range of cells).
#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace specula::store {

struct PriorTables {
  std::vector<double> wavelengths;  ///< the training grids' bands (nm)
  std::vector<double> knots;        ///< channel knot wavelengths (nm)
  std::vector<double> variances;    ///< k
  double epsilon = 0;
  std::vector<float> reference;  ///< one value per cell
  std::vector<float> mean;       ///< one value per cell
  /// one value per cell, or empty: a prior of version 1, written before the ceiling was kept
  std::vector<float> ceiling;
  std::vector<float> components;  ///< k x cells, row-major; or empty, and component_blocks makes them
  /// When components is empty: fills out with the k x count components of cells [first, first + count), row-major;
  /// add_prior calls it for consecutive blocks of kPriorBlockCells cells (the last may be shorter), in order.
  std::function<void(std::size_t first, std::size_t count, std::span<float> out)> component_blocks;
  std::vector<std::string> training;  ///< the training grids, one name per material
  /// the retro band's exponent per band width 1, 2, ... (> 0), or empty: a prior of version <= 2, written before it
  /// was learned
  std::vector<double> retro_exponents;
  /// the retro band's rise maps, 2 w^2 values per width w = 1 .. W (W the exponents' count; finite), or empty: a prior
  /// of version <= 3, written before they were learned
  std::vector<double> retro_rise;
  std::string command_line;  ///< recorded as its provenance; empty: the transaction's
};

/// The values of a prior's retro rise maps for band widths 1 .. widths: 2 w^2 per width w (its 2w x w map).
std::size_t retro_rise_values(std::size_t widths);

/// Cells per block of a prior's components: add_prior writes (and asks component_blocks for) this many at a time.
inline constexpr std::size_t kPriorBlockCells = std::size_t(1) << 16;

}  // namespace specula::store
