#pragma once
// The piecewise-bilinear 2D warp the RGL material format is defined through: Mitsuba 3's Marginal2D<Float, D, true>
// (core/distr_2d.h) and pbrt-v4's PiecewiseLinear2D (util/sampling.h). A W x H grid of values spans [0, 1]^2 with
// nodes at i / (W - 1), j / (H - 1) and is interpolated bilinearly; up to three parameters select and linearly blend
// slices of such grids. With a CDF the values are a density: a uniform point is warped by the marginal CDF over rows
// and the conditional CDF over columns of the continuous interpolant, and `invert` maps back. Arithmetic follows the
// renderers (float tables, the same clamping and near-constant cases) so a file means here what it means there.
#include <array>
#include <cstddef>
#include <span>
#include <vector>

namespace specula::codec {

/// A point of [0, 1]^2 and the density there.
struct WarpPoint {
  double x = 0, y = 0, pdf = 0;
};

/// The table entries an interpolated value blends: value = sum of weight[k] * data[index[k]] for k < n.
struct WarpStencil {
  std::array<std::size_t, 32> index{};
  std::array<double, 32> weight{};
  int n = 0;
};

class Warp2D {
 public:
  Warp2D() = default;
  /// `data`: slices of height x width values, the parameters' slices outermost in the order of `params` (the first
  /// slowest); params[d] lists the parameter values slice d is tabulated at (ascending). With `density` the slices are
  /// normalised to integrate to 1 and CDFs are built (the renderers' vndf and luminance); without, values are
  /// interpolated as stored (ndf, sigma, spectra). Throws UsageError for width or height below 2, more than 3
  /// parameters, an empty parameter list or a data size that does not match.
  Warp2D(std::span<const float> data, std::size_t width, std::size_t height, std::vector<std::vector<float>> params,
         bool density);

  /// The interpolated value (density, with `density`) at (x, y) clamped to [0, 1]^2, the parameters `param`.
  double eval(double x, double y, std::span<const double> param) const;
  /// eval at (x, y) for each value of the last parameter in turn into out (one value each), the other parameters from
  /// `param`: one table lookup for all channels of a spectrum. Throws UsageError for a density or parameterless table
  /// or a wrong out size.
  void eval_last(double x, double y, std::span<const double> param, std::span<double> out) const;
  /// The entries eval blends at (x, y) for a table without `density`, the first `dims` parameters from `param` and
  /// the others at their first value; indices into `data` as given to the constructor.
  WarpStencil stencil(double x, double y, std::span<const double> param, std::size_t dims) const;
  /// Warps the uniform point (x, y) (clamped to [eps, 1 - eps]) to the density; needs `density`.
  WarpPoint sample(double x, double y, std::span<const double> param) const;
  /// The uniform point that `sample` maps to (x, y) (clamped to [0, 1]^2), and the density at (x, y); needs `density`.
  WarpPoint invert(double x, double y, std::span<const double> param) const;

  std::size_t width() const { return w_; }
  std::size_t height() const { return h_; }

 private:
  struct Corners {
    std::array<std::size_t, 8> slice{};
    std::array<double, 8> weight{};
    int n = 0;
  };
  Corners corners(std::span<const double> param, std::size_t dims) const;  // blends the first dims parameters
  struct Patch {
    std::size_t ix = 0, iy = 0;
    double fx = 0, fy = 0;
  };
  Patch patch(double x, double y) const;  // the bilinear patch holding (x, y) clamped to [0, 1]^2
  double lookup(const std::vector<float>& a, std::size_t stride, std::size_t index, const Corners& c) const;

  std::size_t w_ = 0, h_ = 0;
  std::vector<std::vector<float>> params_;
  std::vector<std::size_t> param_stride_;  // in slices; 0 for a parameter with one value
  std::vector<float> data_, marginal_, conditional_;
  bool density_ = false;
};

/// A density table (slices of height x width values, as Warp2D takes it with `density`) on new_height x new_width
/// nodes whose warp follows the original's: each new row is the original interpolant's row at its v, refitted so that
/// its CDF over the columns matches that row's, and the rows' integrals are refitted so that their CDF over the rows
/// matches the original's marginal (each a non-negative least-squares fit of the CDF at 8 points per original
/// interval); every slice keeps its integral. Point samples at the new nodes would instead lose the mass of a peak
/// between them (docs/brdf.md, Export). Both sizes unchanged: the data as it is. UsageError for a side below 2 or a
/// data size that is not a multiple of width x height.
std::vector<float> resample_density(std::span<const float> data, std::size_t width, std::size_t height,
                                    std::size_t new_width, std::size_t new_height);

}  // namespace specula::codec
