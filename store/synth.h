#pragma once
// A realistic synthetic database of hyperspectral radiance images, so benchmarks and the demo need no
// outside data: regions of smooth natural-looking reflectances under CIE daylight of varied CCT, shading,
// shadows lit by sky, sensor noise, masked rectangles.
#include <cstdint>

#include "specula/core/wavelengths.h"
#include "specula/store/cube.h"

namespace specula::store {

struct SynthOptions {
  std::size_t images = 4;
  std::size_t height = 256, width = 256;
  std::uint64_t seed = 1;
  WavelengthGrid wavelengths = WavelengthGrid::range(420, 720, 10);
  double noise = 0.01;  ///< sensor noise: std of the read noise relative to the image's mean radiance
};

/// Image `index` of the database described by `options`: the same (options, index) always gives the same
/// cube, on any thread count. Units "radiance"; mask marks the masked rectangles invalid.
Cube synthesize_image(const SynthOptions& options, std::size_t index);

}  // namespace specula::store
