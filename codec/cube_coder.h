#pragma once
// Entropy coding for .spc version 2, through the adaptive binary range coder of codec/range_coder.h
// (docs/codec-format.md): one cube of quantised wavelet coefficients (codec/wavelet.h's layout): subbands from the
// final low cube to the finest, each skipped whole or by blocks when all zero, in raster order; the low cube by
// differences along axis 2 and every detail coefficient by its significance in the context of its level, its
// significant causal neighbours and its parent, then its magnitude (an adaptive "> 1" bit and an Exp-Golomb code
// with adaptive exponent bits) and its sign; and a 0/1 mask by its causal neighbours and a prior.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "specula/codec/wavelet.h"

namespace specula::codec {

/// Codes the quantised coefficients `q` (one per value of `layout`'s cube).
std::vector<std::uint8_t> encode_cube(std::span<const std::int32_t> q, const wavelet::CubeLayout& layout);
/// Decodes what encode_cube wrote into `q`; false when the stream ran out before the cube did (truncated or corrupt),
/// in which case `q` holds garbage but nothing outside it was touched.
bool decode_cube(std::span<const std::uint8_t> bytes, const wavelet::CubeLayout& layout, std::span<std::int32_t> q);

/// Codes a 0/1 mask of dims[0] x dims[1] x dims[2] cells (axis 2 contiguous) in the context of six causal
/// neighbours, the cell mirrored about the middle of axis 2 once it is coded, and `prior` (a 0/1 mask of the same
/// size both sides know, e.g. the cells above the horizon).
std::vector<std::uint8_t> encode_mask(std::span<const std::uint8_t> mask, std::span<const std::uint8_t> prior,
                                      const std::array<std::size_t, 3>& dims);
/// Decodes what encode_mask wrote into `mask`; false when the stream ran out first (truncated or corrupt).
bool decode_mask(std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> prior,
                 const std::array<std::size_t, 3>& dims, std::span<std::uint8_t> mask);

}  // namespace specula::codec
