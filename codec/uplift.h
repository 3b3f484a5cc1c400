#pragma once
// RGB -> spectrum (reference Appendix A): the RGB equations A x = c stacked with second differences
// weighted by alpha (eq A.3) and solved in the least-squares sense, then negative values clamped to 0; and a
// non-negative variant that solves the same least squares subject to x >= 0 (bounded least squares).
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "specula/codec/merl.h"
#include "specula/core/nnls.h"
#include "specula/store/grid.h"

namespace specula::codec {

/// Solutions of the bounded problem for recently met active sets, reused when their optimality conditions
/// hold for a new RGB (neighbouring cells of a BRDF share them); one per thread. On a miss the core NNLS
/// (core/nnls.h) solves, warm-started from the most recent set, and its optimal passive set becomes an entry.
class UpliftCache {
 public:
  /// Calls answered from a cached active set.
  std::size_t hits() const { return hits_; }
  /// Calls that needed the NNLS solver.
  std::size_t misses() const { return misses_; }

 private:
  friend class Uplift;
  struct Entry {
    std::uint64_t passive = 0;
    Eigen::Matrix<double, Eigen::Dynamic, 3> x;  // x = x * rgb (zero rows outside the passive set)
    Eigen::Matrix<double, Eigen::Dynamic, 3> w;  // gradient A^T rgb - G x = w * rgb
  };
  std::vector<Entry> entries_;  // most recent first
  std::size_t hits_ = 0, misses_ = 0;
};

/// Eq A.3 for one set of RGB weights and one alpha; solving is thread-safe.
class Uplift {
 public:
  /// weights: 3 x B with B >= 3 (RGB of a spectrum, e.g. rgb_weights()); alpha >= 0 and finite, else UsageError.
  Uplift(const Eigen::Matrix<double, 3, Eigen::Dynamic>& weights, double alpha);
  std::size_t bands() const { return std::size_t(system_.cols()); }
  double alpha() const { return alpha_; }
  /// The (3 + B - 2) x B matrix [A; alpha D] of eq A.3.
  const Eigen::MatrixXd& system() const { return system_; }
  /// The least-squares solution of eq A.3 for rgb, before clamping (may hold negative values).
  void solve(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x) const;
  /// Appendix A as published: solve(), then negative values set to 0; returns true when any were.
  bool clamped(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x) const;
  /// The least squares of eq A.3 subject to x >= 0; returns true when a bound is active. A cache (one per
  /// thread) lets it reuse the active sets of earlier calls.
  bool nonnegative(const Eigen::Vector3d& rgb, Eigen::Ref<Eigen::VectorXd> x, UpliftCache* cache = nullptr) const;

 private:
  double alpha_;
  Eigen::MatrixXd system_;
  Eigen::Matrix<double, Eigen::Dynamic, 3> solve_;  // B x 3: x = solve_ * rgb
  Eigen::MatrixXd gram_;                            // system^T system
  std::optional<GramNnls> nnls_;                    // the bounded problem's solver on gram_
  Eigen::Matrix<double, Eigen::Dynamic, 3> at_;     // A^T: system^T [rgb; 0] = at_ * rgb
};

/// Default alpha of eq A.3 for RGB weights normalised as rgb_weights() (a flat spectrum 1 gives RGB 1): small
/// enough that feasible RGB is reproduced to about 1e-7, so the result is the smoothest spectrum matching it.
inline constexpr double kDefaultUpliftAlpha = 1e-3;

enum class UpliftMethod { clamp, nonnegative };

/// What an uplift of a whole BRDF did.
struct UpliftReport {
  std::size_t cells = 0;        ///< cells with data in all three channels
  std::size_t constrained = 0;  ///< cells where clamping or a bound changed the solution
  double max_rgb_error = 0;     ///< max over cells of |A x - rgb|_inf / max(|rgb|_inf, tiny)
};

/// Uplifts every cell with data of `rgb` into a grid on `uplift`'s wavelengths (scale 1, units 1/sr); cells
/// without data in any channel get -1 in every band. Throws UsageError if wavelengths do not match the bands.
store::Grid uplift_merl(const MerlBrdf& rgb, const WavelengthGrid& wavelengths, const Uplift& uplift,
                        UpliftMethod method, UpliftReport* report = nullptr);

/// Uplifts an RGB image (height x width x 3, channel fastest, rows top to bottom; e.g. radiance of a lat-long
/// environment map) pixel by pixel into out (height x width x bands, band fastest) with `method`; on all threads, one
/// UpliftCache per row so the output does not depend on the thread count; Interrupted between rows. Returns how
/// many pixels clamping or the bound changed. UsageError on sizes; InputError naming the first pixel (x, y) with a
/// negative channel.
std::size_t uplift_image(std::span<const float> rgb, std::size_t width, std::size_t height, const Uplift& uplift,
                         UpliftMethod method, std::span<float> out);

}  // namespace specula::codec
