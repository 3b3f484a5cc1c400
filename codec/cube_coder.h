#pragma once
// Entropy coding of one cube of quantised wavelet coefficients (codec/wavelet.h's layout) for .spc version 2:
// subbands from the final low cube to the finest, each in raster order; the low cube by differences along axis 2
// and every detail coefficient by its significance in the context of its level, its significant causal neighbours
// and its parent, then its magnitude (an adaptive "> 1" bit and an Exp-Golomb code with adaptive exponent bits)
// and its sign, all through the adaptive binary range coder of codec/range_coder.h (docs/codec-format.md).
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

}  // namespace specula::codec
