#pragma once
// Entropy coding of .spc format 4's integer codes (docs/codec-format.md) through the adaptive binary range coder of
// codec/range_coder.h: each sample's four angle indices by an adaptive bit tree per column (the empirical
// distribution of a goniometer's positions), then its magnitude and shape codes, each channel as the value or its
// difference from the previous sample's, by an adaptive zero bit, sign bit, and an Exp-Golomb magnitude with adaptive
// exponent bits and an adaptive leading mantissa bit, one set of contexts per channel.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace specula::codec {

/// The largest |code| of a format-4 magnitude or shape channel (2^27).
inline constexpr std::int64_t kMaxSampleCode = std::int64_t(1) << 27;

/// The integer codes of n samples on k basis spectra.
struct SampleCodeStreams {
  std::size_t n = 0, k = 0;
  std::array<std::uint32_t, 4> palette_size{};  ///< distinct values of each angle column, >= 1
  std::vector<std::uint32_t> index;             ///< n x 4: each angle's position in its column's palette
  std::vector<std::int64_t> mag;                ///< n
  std::vector<std::int64_t> shape;              ///< n x k, sample-major
  std::vector<std::uint8_t> delta;              ///< k + 1 (magnitude, then shapes): 1 codes differences
};

/// Codes `s` (every index below its palette size, every code within +-kMaxSampleCode, delta of size k + 1).
std::vector<std::uint8_t> encode_sample_codes(const SampleCodeStreams& s);
/// Decodes what encode_sample_codes wrote into s's index, mag and shape (n, k, palette_size and delta given); false
/// when the stream ran out first or a decoded value left its range (truncated or corrupt).
bool decode_sample_codes(std::span<const std::uint8_t> bytes, SampleCodeStreams& s);

/// Whether coding a channel's differences from the previous sample costs fewer bits than its values, by the
/// Exp-Golomb length of each.
bool prefer_differences(std::span<const std::int64_t> channel, std::size_t stride, std::size_t offset, std::size_t n);

}  // namespace specula::codec
