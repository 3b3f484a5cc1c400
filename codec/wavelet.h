#pragma once
// The CDF 9/7 wavelet (the lossy filter of JPEG 2000) by lifting, with whole-sample symmetric extension at both
// ends, applied separably to a 3-D cube over several levels (Mallat's pyramid: each level transforms the low cube
// of the previous one along all three axes, lows first). The layout after a forward transform and the subbands of
// each level are described by CubeLayout; .spc version 2 codes the coefficients of such cubes (codec-format.md).
#include <array>
#include <cstddef>
#include <span>

namespace specula::codec::wavelet {

/// Forward 9/7 on `x` in place, then deinterleaved: ceil(n/2) low-pass values followed by floor(n/2) high-pass ones;
/// lines of fewer than 2 samples are left as they are. `scratch` needs n values.
void forward_line(std::span<float> x, std::span<float> scratch);
/// Inverse of forward_line.
void inverse_line(std::span<float> x, std::span<float> scratch);

/// A cube of dims[0] x dims[1] x dims[2] values (axis 2 contiguous) transformed over `levels` levels.
struct CubeLayout {
  std::array<std::size_t, 3> dims{};
  int levels = 0;
  /// Extent per axis of the low cube entering level l (l = 0: the whole cube; l = levels: the final low cube).
  std::array<std::size_t, 3> low(int l) const;
  /// First and one-past-last index along `axis` of the subband of level l (0 = finest) with orientation `o`
  /// (bit a set: high-pass along axis a; 1..7), or of the final low cube for o = 0 and l = levels.
  std::array<std::size_t, 2> range(int l, int o, int axis) const;
  /// L2 norm of the cube that inverse-transforms a unit coefficient in the middle of subband (l, o) (o = 0, l = levels:
  /// the final low cube): the factor by which a quantisation error there reaches the values.
  double synthesis_norm(int l, int o) const;
};

/// Forward transform of a cube in place (`levels` >= 0; every low extent stays >= 1).
void forward_cube(std::span<float> cube, const CubeLayout& layout);
/// Inverse of forward_cube.
void inverse_cube(std::span<float> cube, const CubeLayout& layout);

}  // namespace specula::codec::wavelet
