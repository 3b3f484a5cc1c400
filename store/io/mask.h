#pragma once
// Validity masks as labs keep them: a PNG (the first channel) or a one-band ENVI image (.hdr with its data file,
// the usual byte mask of ENVI workflows). Nonzero is valid; so is anything but ENVI's data ignore value.
#include <cstdint>
#include <filesystem>
#include <vector>

namespace specula::store {

/// A mask: height x width bytes, row-major, 1 = valid.
struct Mask {
  std::size_t width = 0, height = 0;
  std::vector<std::uint8_t> valid;
};

/// Reads a mask from a PNG or a one-band ENVI image (its .hdr, or its data file with the .hdr beside it); throws
/// InputError naming the file when it is neither, is corrupt, or has more than one band.
Mask read_mask(const std::filesystem::path& path);

}  // namespace specula::store
