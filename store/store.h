#pragma once
// The specula store: one HDF5 file holding hyperspectral images, spectral collections, scattered BRDF
// samples, BRDF grids and learned bases. Layout: docs/store-format.md. Reading is through Store; every
// change goes through a StoreWriter transaction that is invisible until commit() (all or nothing).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/wavelengths.h"
#include "store/basis.h"
#include "store/cube.h"
#include "store/h5.h"

namespace specula::store {

inline constexpr const char* kFormatName = "specula-store";
inline constexpr long long kFormatVersion = 1;

/// Dataset compression for new objects.
struct Compression {
  enum class Kind { none, deflate } kind = Kind::deflate;
  int level = 4;
  /// Parses "none", "deflate" or "deflate:LEVEL" (LEVEL 1-9); throws UsageError with the rule.
  static Compression parse(std::string_view spec);
  std::string describe() const;
};

/// What a store knows about one image without reading its pixels.
struct ImageInfo {
  std::string name;
  std::size_t height = 0, width = 0, bands = 0;
  WavelengthGrid wavelengths;
  bool has_fwhm = false;
  std::string units;
  std::uint64_t valid_pixels = 0;
  std::size_t chunk_rows = 0;
  std::string compression;
  Provenance provenance;
};

/// What a store knows about one collection.
struct CollectionInfo {
  std::string name;
  std::size_t size = 0, bands = 0;
  WavelengthGrid wavelengths;
  std::string units;
  std::size_t chunk_rows = 0;
  Provenance provenance;
};

/// What a store knows about one set of scattered BRDF samples.
struct SamplesInfo {
  std::string name;
  std::size_t size = 0, bands = 0;
  WavelengthGrid wavelengths;
  std::string units;
  std::size_t chunk_rows = 0;  ///< samples per storage chunk of the values (read in multiples of it)
  Provenance provenance;
};

/// A B-band BRDF in the MERL half/difference layout: brdf is bands x 90 x 90 x 180 float32 (band slowest,
/// phi_d fastest, the cell order of core/brdf_geometry.h); a negative value means no data; value * scale is in 1/sr.
struct Grid {
  WavelengthGrid wavelengths;
  double scale = 1.0;
  std::vector<float> brdf;
  std::string units = "1/sr";
  Provenance provenance;

  std::size_t bands() const { return wavelengths.size(); }
};

/// What a store knows about one BRDF grid without reading its values.
struct GridInfo {
  std::string name;
  std::size_t bands = 0;
  WavelengthGrid wavelengths;
  double scale = 1.0;
  std::string units;
  std::string compression;
  Provenance provenance;
};

/// What a store knows about one coefficient map: the coefficients of an image's pixels on a basis, kept with a
/// copy of that basis so the map reconstructs its image on its own.
struct CoefficientsInfo {
  std::string name;
  std::string image;   ///< the image the map was computed from
  std::string basis;   ///< the basis's name in the store when the map was written
  std::string method;  ///< "pca" (first k components, eq 7.2) or "nmf" (NNLS on all k components)
  std::size_t height = 0, width = 0, k = 0;
  std::uint64_t valid_pixels = 0;
  std::size_t chunk_rows = 0;
  std::string compression;
  Provenance provenance;
};

/// A store opened read-only. Copies share the open file.
class Store {
 public:
  /// Opens `path`; throws InputError if it is missing, not HDF5, not a specula store, or of a newer format.
  static Store open(const std::filesystem::path& path);

  const std::filesystem::path& path() const { return path_; }
  /// The file's name, used as the prefix of every message about it.
  std::string label() const { return path_.filename().string(); }
  hid_t file() const { return file_->get(); }

  std::vector<std::string> images() const;
  std::vector<std::string> collections() const;
  std::vector<std::string> samples() const;
  std::vector<std::string> grids() const;
  std::vector<std::string> bases() const;
  std::vector<std::string> coefficients() const;
  /// Format version and provenance attributes of the file root.
  long long format_version() const { return version_; }

  /// Metadata of image `name`; throws InputError listing the images when absent.
  ImageInfo image_info(const std::string& name) const;
  /// Metadata of collection `name`; throws InputError listing the collections when absent.
  CollectionInfo collection_info(const std::string& name) const;
  /// Metadata of samples `name`; throws InputError listing them when absent.
  SamplesInfo samples_info(const std::string& name) const;
  /// Metadata of grid `name`; throws InputError listing the grids when absent or malformed.
  GridInfo grid_info(const std::string& name) const;
  /// The whole grid (bands x 90 x 90 x 180 values) in memory.
  Grid read_grid(const std::string& name) const;
  /// The whole image in memory (for export and previews; analysis streams with BlockReader instead).
  Cube read_image(const std::string& name) const;
  /// Spectrum of pixel (x, y) of image `name` into out (bands values, read alone); false when masked.
  /// UsageError when x, y lie outside the image or out has the wrong size.
  bool read_pixel(const std::string& name, std::size_t x, std::size_t y, std::span<float> out) const;
  /// The whole collection in memory.
  Collection read_collection(const std::string& name) const;
  /// Basis `name`; throws InputError listing the bases when absent or malformed.
  Basis read_basis(const std::string& name) const;
  /// Metadata of coefficient map `name`; throws InputError listing the maps when absent or malformed.
  CoefficientsInfo coefficients_info(const std::string& name) const;
  /// The basis stored with coefficient map `name` (its k components, wavelengths and, for PCA, mean).
  Basis coefficients_basis(const std::string& name) const;
  /// Rows [y0, y0 + rows) of coefficient map `name`: coefficients (rows x width x k, component fastest; zeros at
  /// masked pixels) and, when not empty, mask (rows x width, 1 = valid). UsageError on out-of-range rows or sizes.
  void read_coefficient_rows(const std::string& name, std::size_t y0, std::size_t rows, std::span<float> coefficients,
                             std::span<std::uint8_t> mask) const;
  /// Rows [first, first + count) of samples `name`: angles (count x 4, radians) and values (count x B); an
  /// empty span skips that dataset.
  void read_samples(const std::string& name, std::size_t first, std::size_t count, std::span<double> angles,
                    std::span<float> values) const;

 private:
  std::filesystem::path path_;
  std::shared_ptr<h5::Id> file_;
  long long version_ = 0;
};

/// Options for a write transaction.
struct WriteOptions {
  Compression compression;
  bool replace = false;               ///< allow replacing an object of the same name
  std::string command_line;           ///< recorded as provenance on every object written
};

/// A transaction on a store: changes go to a private copy that replaces the store only on commit();
/// an error, Ctrl-C or kill -9 before that leaves the store byte-identical.
class StoreWriter {
 public:
  /// Starts a transaction on `path`, which is created if absent; an existing file must be a specula store.
  StoreWriter(const std::filesystem::path& path, WriteOptions options);
  StoreWriter(const StoreWriter&) = delete;
  StoreWriter& operator=(const StoreWriter&) = delete;
  ~StoreWriter();

  /// Adds image `name` (chunked by rows, compressed); throws InputError on NaN/Inf, size or name problems.
  void add_image(const std::string& name, const Cube& cube);
  /// Adds collection `name`.
  void add_collection(const std::string& name, const Collection& collection);
  /// Adds basis `name` (float64 datasets; empty members are not written).
  void add_basis(const std::string& name, const Basis& basis);
  /// Adds BRDF grid `name` (chunked, compressed); throws InputError on NaN/Inf or a bad scale, UsageError on sizes.
  void add_grid(const std::string& name, const Grid& grid);
  /// Creates an empty extendible set of scattered BRDF samples.
  void create_samples(const std::string& name, const WavelengthGrid& wavelengths, const std::string& units,
                      const Provenance& provenance);
  /// Appends n samples: angles (n x 4: theta_i, phi_i, theta_o, phi_o in radians) and values (n x B).
  void append_samples(const std::string& name, std::span<const double> angles, std::span<const float> values);
  /// Creates coefficient map `name` for the height x width pixels of `image` on `basis` (all its k rows; a copy is
  /// stored with the map), chunked by chunk_rows whole rows; rows are then written by write_coefficient_rows.
  void create_coefficients(const std::string& name, const CoefficientsInfo& info, const Basis& basis);
  /// Writes rows [y0, y0 + rows) of map `name`: coefficients (rows x width x k) and mask (rows x width, 1 = valid);
  /// masked pixels are stored as zeros. InputError on a non-finite coefficient at a valid pixel.
  void write_coefficient_rows(const std::string& name, std::size_t y0, std::size_t rows,
                              std::span<const float> coefficients, std::span<const std::uint8_t> mask);
  /// Makes every change visible at the store's path at once.
  void commit();

  /// The open temporary file (for other specula libraries adding their own objects in the same transaction).
  hid_t file() const { return file_.get(); }
  std::string label() const { return target_.filename().string(); }
  const WriteOptions& options() const { return options_; }

 private:
  void check_name(const std::string& kind, const std::string& group, const std::string& name);
  std::filesystem::path target_;
  WriteOptions options_;
  struct Temp;
  std::unique_ptr<Temp> temp_;
  h5::Id file_;
};

/// Validates an object name: 1-255 chars of [A-Za-z0-9_.+-], not starting with '.'; throws UsageError.
void validate_name(const std::string& name, const std::string& kind);
/// Writes provenance attributes (source_file, importer, specula_version, command_line, created_utc) on obj.
void write_provenance(hid_t obj, const Provenance& p, const std::string& command_line, std::string_view ctx);
/// Reads provenance attributes written by write_provenance (missing ones empty).
Provenance read_provenance(hid_t obj, std::string_view ctx);
/// Current UTC time as ISO 8601 ("2026-11-22T02:25:19Z").
std::string utc_now();
/// Test hook: after `n` more chunk writes, the next one fails as a full disk would (-1 disables).
void inject_write_failure_after(long long n);

}  // namespace specula::store
