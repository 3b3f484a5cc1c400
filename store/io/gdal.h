#pragma once
// Multi-band rasters through GDAL (GeoTIFF and every raster format GDAL reads), read row strip by row strip so an
// image never has to fit in memory.
//
// Wavelengths, first found wins: per band, a `wavelength` item (with `wavelength_units`, as GDAL's ENVI driver and
// GeoTIFFs converted from ENVI carry it) or `CENTRAL_WAVELENGTH_UM` in the default, ENVI or IMAGERY metadata domain;
// else a band description ending in a wavelength ("Band 1 (450.0 nm)", "450 nm", "0.45 um"); else the dataset's ENVI
// domain `wavelength` list; else the caller's grid. Units: nanometers unless stated otherwise, or unless every value
// lies in [0.2, 20] and not all are integers (micrometres). FWHM comes the same way from `fwhm` / `FWHM_UM`.
// A pixel is masked when any band holds that band's nodata value (or NaN when nodata is NaN) or the dataset's mask
// band (alpha, .msk) marks it invalid. Band scale and offset, when set, are applied.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"

namespace specula::store {

/// One raster opened through GDAL for reading by row strips (not thread-safe; one per thread).
class GdalRaster {
 public:
  /// Opens `path`; InputError naming the file (with GDAL's message) when GDAL cannot read it as a raster, it has a
  /// complex data type, or it carries no wavelengths and `fallback` is empty (asking for the `wavelengths` option).
  GdalRaster(const std::filesystem::path& path, const WavelengthGrid& fallback);
  GdalRaster(const GdalRaster&) = delete;
  GdalRaster& operator=(const GdalRaster&) = delete;
  ~GdalRaster();

  std::size_t height() const { return height_; }
  std::size_t width() const { return width_; }
  std::size_t bands() const { return wavelengths_.size(); }
  const WavelengthGrid& wavelengths() const { return wavelengths_; }
  /// FWHM per band in nm, or empty.
  const std::vector<double>& fwhm() const { return fwhm_; }
  /// The GDAL driver's short name, e.g. "GTiff".
  const std::string& driver() const { return driver_; }
  /// Reads rows [y0, y0 + rows) into spectra (rows x width x bands, band fastest, as float32) and mask (rows x width,
  /// 1 = valid); InputError naming the file and rows, with GDAL's message, when the data cannot be read.
  void read_rows(std::size_t y0, std::size_t rows, std::span<float> spectra, std::span<std::uint8_t> mask);

 private:
  std::string file_;
  void* dataset_ = nullptr;
  std::size_t height_ = 0, width_ = 0;
  WavelengthGrid wavelengths_;
  std::vector<double> fwhm_;
  std::string driver_;
  std::vector<double> nodata_, scale_, offset_;
  std::vector<bool> has_nodata_;
  bool scaled_ = false, dataset_mask_ = false;
};

/// Bytes of the per-strip buffers read_rows needs for `rows` rows of a width x bands raster.
std::uint64_t gdal_strip_bytes(std::size_t width, std::size_t bands, std::size_t rows);

}  // namespace specula::store
