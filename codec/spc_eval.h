#pragma once
// Evaluating a coded spectral BRDF without decoding it to a grid: the .spc's coefficient form (k floats per MERL
// cell) and its basis, looked up as MERL's BRDFRead.cpp does. The MERL lookup takes the value of the nearest
// cell (the one holding the direction pair's half/difference angles) and interpolates nothing beyond that, so
// neither does this: x_b(wi, wo) = max(0, sum_j a_j(cell) V_jb) * scale, in 1/sr.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "specula/codec/spc.h"

namespace specula::codec {

/// The MERL cell index of each direction pair: cells[i] = brdf::merl_index(brdf::merl_cell(brdf::half_diff(wi_i,
/// wo_i))) with the float inputs taken as doubles (wi, wo: n x 3 floats, x y z per direction, local frame, z the
/// normal, any length). Computed in float and redone in double whenever a pair lies near a cell boundary or the
/// float angles are ill-conditioned, so it equals the double lookup. Mismatched sizes: UsageError.
void merl_indices(std::span<const float> wi, std::span<const float> wo, std::span<std::uint32_t> cells);

/// A decoded .spc held in coefficient form and evaluated per direction pair; const methods are thread-safe.
class SpcBrdf {
 public:
  /// Takes the coefficients over (basis k x B with 1 <= k, B >= 1; values k per cell; scale > 0 and finite),
  /// else UsageError naming what does not match.
  explicit SpcBrdf(SpcCoefficients&& coefficients);

  /// Coefficients per cell.
  std::size_t k() const { return k_; }
  /// Values per evaluation, one per wavelength.
  std::size_t bands() const { return bands_; }
  const WavelengthGrid& wavelengths() const { return wavelengths_; }
  /// The coded grid's source and the basis reference, as the .spc records them.
  const std::string& source() const { return source_; }
  const std::string& reference() const { return reference_; }
  /// Bytes held: the coefficients (k floats per cell), the validity map and the basis.
  std::size_t memory_bytes() const;

  /// True when MERL cell `cell` (< brdf::kMerlCells) holds data.
  bool has_data(std::size_t cell) const { return valid_[cell] != 0; }
  /// The B values (1/sr) of MERL cell `cell` (< brdf::kMerlCells) into out (size B, else UsageError): 0 in a
  /// cell without data.
  void evaluate_cell(std::size_t cell, std::span<float> out) const;
  /// The B values (1/sr) at one direction pair (local frame, z the normal, any length) into out (size B, else
  /// UsageError), the cell found as brdf::merl_cell(brdf::half_diff(wi, wo)); returns false, with zeros, when
  /// that cell holds no data.
  bool evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<float> out) const;
  /// n direction pairs at once (wi, wo: n x 3 floats, x y z per direction; cells as merl_indices) into out
  /// (n x B floats, band fastest; 0 where a cell holds no data), on all threads in fixed chunks, so the result
  /// does not depend on the thread count. Sizes that do not match: UsageError.
  void evaluate(std::span<const float> wi, std::span<const float> wo, std::span<float> out) const;

 private:
  void expand(std::size_t cell, float* out) const;

  WavelengthGrid wavelengths_;
  std::string source_, reference_;
  std::size_t k_ = 0, bands_ = 0, padded_ = 0;
  Buffer<float> values_;             // kMerlCells x k, the decoded form's own (on huge pages where offered)
  std::vector<std::uint8_t> valid_;  // kMerlCells
  std::vector<float> basis_;         // k x padded_, the rows V times scale, zero beyond B
};

}  // namespace specula::codec
