#pragma once
// In-memory objects that importers produce and exporters consume. The database itself is never held in
// memory: these hold one image or one collection at a time.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"

namespace specula::store {

/// Where an object came from, stored as attributes next to it.
struct Provenance {
  std::string source_file;   ///< path as given by the user
  std::string importer;      ///< e.g. "envi", "mat", "png-stack", "exr", "csv", "synth-db"
  std::string command_line;  ///< the specula command that made it
  std::string created_utc;   ///< ISO 8601, filled by the store when empty
};

/// One hyperspectral image: data is H x W x B float32, band fastest: data[(y * width + x) * bands + b].
struct Cube {
  std::size_t height = 0, width = 0, bands = 0;
  std::vector<float> data;
  std::vector<std::uint8_t> mask;  ///< empty = every pixel valid; else height*width, 1 = valid
  WavelengthGrid wavelengths;
  std::vector<double> fwhm;       ///< empty or one per band (nm)
  std::string units = "unknown";  ///< "reflectance", "radiance", "counts" or free text
  Provenance provenance;

  float* pixel(std::size_t y, std::size_t x) { return data.data() + (y * width + x) * bands; }
  const float* pixel(std::size_t y, std::size_t x) const { return data.data() + (y * width + x) * bands; }
  bool valid(std::size_t y, std::size_t x) const { return mask.empty() || mask[y * width + x] != 0; }
  /// Allocates data for h x w x b (zeroed) and clears the mask.
  void resize(std::size_t h, std::size_t w, std::size_t b) {
    height = h;
    width = w;
    bands = b;
    data.assign(h * w * b, 0.0f);
    mask.clear();
  }
};

/// N named spectra on one grid: values is N x B float32, band fastest.
struct Collection {
  std::vector<std::string> names;
  std::vector<float> values;
  WavelengthGrid wavelengths;
  std::string units = "unknown";
  Provenance provenance;

  std::size_t size() const { return names.size(); }
  std::size_t bands() const { return wavelengths.size(); }
};

}  // namespace specula::store
