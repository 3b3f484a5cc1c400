#pragma once
// The stored values of an RGL material (codec/rgl_bsdf.h) fitted to a BRDF on the MERL grid by weighted least squares.
// A renderer's value at a pair of directions is linear in the stored values (RglEvaluator::stencil: bilinear on the
// sample square, linear between incident elevations, times D / (4 sigma cos theta_o)), so the values that best
// reproduce the BRDF at every cell centre, with either direction tabulated, solve one sparse linear system: the
// normal equations of the cells' relative errors. Point samples at the nodes reproduce the BRDF at the nodes only;
// between them bilinear interpolation of f cos 4 sigma / D, multiplied back by D, misses wherever D changes faster
// than the nodes are spaced (docs/brdf.md, Export).
#include <span>

#include "specula/codec/rgl_bsdf.h"

namespace specula::codec {

/// How rgl_fit_values weighs cells and holds the values no cell constrains.
struct RglFitSettings {
  /// Weight of the starting values (a Tikhonov term pulling each value towards them), relative to the mean diagonal
  /// of the normal matrix; keeps values no cell sees, and the system, well defined.
  double prior = 1e-4;
  /// Errors are relative to max(Y, floor * median Y), Y the cell's luminance: dark cells are not fitted to noise.
  double floor = 1e-2;
  /// Cells weighted by (cos theta_i cos theta_o)^cosine_power at their centre.
  double cosine_power = 1;
  /// Conjugate gradients (Jacobi preconditioned) per channel stop at this relative residual or iteration count.
  double tolerance = 1e-6;
  std::size_t max_iterations = 500;
};

/// Replaces the stored values of `b` (its ndf, sigma, theta_i, vndf and resolution kept; its values the starting
/// point) by the least-squares fit to `merl` (b.channels() x MERL cells, channel slowest, negative: no data) times
/// `scale`, then clamps them at 0; the luminance is left to the caller. `lum_weights`: the luminance of a value per
/// channel. The normal equations are summed over a fixed partition of the cells, so the result does not depend on
/// the thread count. UsageError for sizes that disagree or a non-positive floor.
void rgl_fit_values(RglBsdf& b, std::span<const float> merl, double scale, std::span<const double> lum_weights,
                    const RglFitSettings& settings);

}  // namespace specula::codec
