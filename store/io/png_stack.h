#pragma once
// PNG images: band stacks (one 8/16-bit grayscale PNG per band, CAVE naming) and 8-bit RGB output.
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "specula/store/cube.h"

namespace specula::store {

/// Reads one grayscale PNG per band (8 or 16 bit, scaled to [0, 1]); all must share a size. `files` are in
/// band order and match `wavelengths` one to one. A directory expands to its *.png sorted by name.
Cube read_png_stack(const std::vector<std::filesystem::path>& files, const WavelengthGrid& wavelengths);
/// Writes 8-bit RGB (rgb.size() == 3 * width * height, row-major) atomically.
void write_png_rgb8(const std::filesystem::path& path, std::size_t width, std::size_t height,
                    std::span<const std::uint8_t> rgb);
/// 8-bit RGB (rgb.size() == 3 * width * height, row-major) encoded as PNG bytes in memory (fast deflate level).
std::vector<std::uint8_t> encode_png_rgb8(std::size_t width, std::size_t height, std::span<const std::uint8_t> rgb);
/// Writes a 16-bit grayscale PNG (value.size() == width * height) atomically; fast trades size for speed.
void write_png_gray16(const std::filesystem::path& path, std::size_t width, std::size_t height,
                      std::span<const std::uint16_t> value, bool fast = false);
/// A decoded PNG: channels 1..4, bit depth 8 or 16 (samples widened to uint16).
struct PngImage {
  std::size_t width = 0, height = 0, channels = 0;
  int bit_depth = 8;
  std::vector<std::uint16_t> samples;
};
/// Reads any PNG; throws InputError naming the file on corruption.
PngImage read_png(const std::filesystem::path& path);

}  // namespace specula::store
