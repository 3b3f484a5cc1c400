#pragma once
// OpenEXR: spectral images in the layout of Fichet et al. 2021 and linear RGB previews.
#include <filesystem>
#include <span>
#include <vector>

#include "specula/store/cube.h"

namespace specula::store {

/// Reads a spectral EXR: reflective channels "T.<nm>,<frac>nm" (units "reflectance"), else emissive
/// "S0.<nm>,<frac>nm" (units "radiance"); an "A" channel is read as the mask (<= 0.5 = masked); other channels
/// ignored; throws InputError if no spectral channel is present.
Cube read_spectral_exr(const std::filesystem::path& path);
/// Writes `cube` as a spectral EXR (float32, T.* if units == "reflectance", else S0.*), exact round trip; a mask
/// is written as the alpha channel "A" (0 = masked) and read back from it.
void write_spectral_exr(const std::filesystem::path& path, const Cube& cube);
/// Linear RGB of an EXR with R, G and B channels (3 floats per pixel, rows top to bottom); InputError if the
/// file is unreadable, lacks a channel, or holds a non-finite value.
std::vector<float> read_exr_rgb(const std::filesystem::path& path, std::size_t& width, std::size_t& height);
/// True when the EXR has spectral channels (the layout of Fichet et al. 2021); InputError if unreadable.
bool exr_is_spectral(const std::filesystem::path& path);
/// Writes linear RGB float (rgb.size() == 3 * width * height) as a half-float RGB EXR, atomically.
void write_exr_rgb(const std::filesystem::path& path, std::size_t width, std::size_t height,
                   std::span<const float> rgb);

}  // namespace specula::store
