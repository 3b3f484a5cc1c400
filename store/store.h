#pragma once
// The specula store: a small HDF5 root file (the index, one external link per object) beside a data directory of
// immutable object files holding hyperspectral images, spectral collections, scattered BRDF samples, BRDF grids,
// learned bases, coefficient maps and calibrations. Layout and commit protocol: docs/store-format.md. Reading is
// through Store (one committed state, never blocked); every change goes through a StoreWriter transaction that
// writes only its own objects and is invisible until commit() (all or nothing, serialised with other writers).
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/basis.h"
#include "specula/store/cube.h"
#include "specula/store/grid.h"
#include "specula/store/layout.h"

namespace specula::store {

namespace h5 {
class Id;
}  // namespace h5
struct StoreAccess;
struct WriterState;

inline constexpr const char* kFormatName = "specula-store";
inline constexpr long long kFormatVersion = 2;

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
  bool variance = false;       ///< each value carries its noise variance (samples_version 2; docs/store-format.md)
  Provenance provenance;
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
  /// The tables of the RGL file the grid was imported from, when it carries them (Grid::parameterisation).
  std::optional<GridParameterisation> parameterisation;
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

/// An object of a kind another library defines (kind "acquire": acquire's calibrations): float64 vectors and
/// matrices and string attributes by name, with provenance. Written by StoreWriter::add_record, read by
/// Store::read_record.
struct PriorTables;

struct Record {
  std::string label;  ///< "<store>: /<kind>/<name>", the prefix of messages about it (set by read_record)
  std::vector<std::pair<std::string, Eigen::MatrixXd>> matrices;     ///< 2-D datasets (row-major on disk)
  std::vector<std::pair<std::string, std::vector<double>>> vectors;  ///< 1-D datasets
  std::vector<std::pair<std::string, std::string>> texts;            ///< string attributes besides provenance
  Provenance provenance;

  /// Matrix `name`; InputError starting with label when the record has none.
  const Eigen::MatrixXd& matrix(std::string_view name) const;
  /// Vector `name`; InputError starting with label when the record has none.
  const std::vector<double>& vector(std::string_view name) const;
  /// Text `name`; InputError starting with label when the record has none.
  const std::string& text(std::string_view name) const;
};

/// A store opened read-only: one committed state, kept readable (its data files are not reclaimed) while any copy of
/// this object lives. Copies share the open file.
class Store {
 public:
  /// Opens `path`; throws InputError if it is missing, not HDF5, not a specula store, or of a newer format.
  static Store open(const std::filesystem::path& path);

  const std::filesystem::path& path() const { return path_; }
  /// The file's name, used as the prefix of every message about it.
  std::string label() const { return path_.filename().string(); }

  std::vector<std::string> images() const;
  std::vector<std::string> collections() const;
  std::vector<std::string> samples() const;
  std::vector<std::string> grids() const;
  std::vector<std::string> bases() const;
  std::vector<std::string> coefficients() const;
  /// Names of the objects of `kind` (one of layout::kKinds, e.g. "acquire" for calibrations), in name order.
  std::vector<std::string> objects(std::string_view kind) const;
  /// Format version of the root: 2 (current), or 1 (a single-file store: readable, written only after upgrade()).
  long long format_version() const { return version_; }
  /// The committed state this object reads (format 2; empty entries and generation 0 for format 1).
  const layout::Index& index() const;
  /// True when a commit replaced the root since this state was opened (open() again to see it).
  bool stale() const;
  /// When the store was created (the root's created_utc attribute, ISO 8601; empty when absent).
  std::string created_utc() const;
  /// The data directory of a format-2 store.
  std::filesystem::path data_dir() const { return layout::data_dir(path_, index()); }

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
  /// Rows [first, first + count) of samples `name`: angles (count x 4, radians), values (count x B) and, for samples
  /// with a variance, their variances (count x B); an empty span skips that dataset. UsageError for a variance
  /// asked of samples without one.
  void read_samples(const std::string& name, std::size_t first, std::size_t count, std::span<double> angles,
                    std::span<float> values, std::span<float> variance = {}) const;
  /// Record `name` of `kind` (written by StoreWriter::add_record); InputError when absent or malformed.
  Record read_record(const std::string& kind, const std::string& name) const;
  /// Prior `name` (store/prior.h) of `cells` cells, with its components or (components false) without them (their
  /// shape checked); InputError naming what the store holds when absent or malformed.
  PriorTables read_prior(const std::string& name, std::size_t cells, bool components = true) const;
  /// The k x count components of cells [first, first + count) of prior `name` into out (row-major), reading only the
  /// chunks that hold them; UsageError on a range or size that does not fit, InputError for a non-finite value.
  void read_prior_components(const std::string& name, std::size_t first, std::size_t count, std::span<float> out) const;

 private:
  friend struct StoreAccess;
  struct Snapshot;
  std::filesystem::path path_;
  std::shared_ptr<h5::Id> file_;
  std::shared_ptr<const Snapshot> snapshot_;
  long long version_ = 0;
};

/// Options for a write transaction.
struct WriteOptions {
  Compression compression;
  bool replace = false;      ///< allow replacing an object of the same name
  std::string command_line;  ///< recorded as provenance on every object written
};

/// A transaction on a store: each object goes to its own new data file; commit() links them all into the root at
/// once. An error, Ctrl-C or kill -9 before that leaves the store as it was (the files left are reclaimed later).
class StoreWriter {
 public:
  /// Starts a transaction on `path`, which is created on commit if absent; an existing file must be a format-2 store.
  StoreWriter(const std::filesystem::path& path, WriteOptions options);
  StoreWriter(const StoreWriter&) = delete;
  StoreWriter& operator=(const StoreWriter&) = delete;
  ~StoreWriter();

  /// Adds image `name` (chunked by rows, compressed); throws InputError on NaN/Inf, size or name problems.
  void add_image(const std::string& name, const Cube& cube);
  /// Creates image `name` (height x width x wavelengths.size(), chunked as add_image does) to be filled by
  /// write_image_rows; fwhm empty or one per band. Returns the rows per storage chunk: strips of whole chunks write
  /// fastest.
  std::size_t create_image(const std::string& name, std::size_t height, std::size_t width,
                           const WavelengthGrid& wavelengths, std::span<const double> fwhm, const std::string& units,
                           const Provenance& provenance);
  /// Writes rows [y0, y0 + rows): spectra (rows x width x bands, band fastest) and mask (rows x width, 1 = valid; empty
  /// = all valid); InputError on a non-finite value at a valid pixel. Every row must be written before commit().
  void write_image_rows(const std::string& name, std::size_t y0, std::size_t rows, std::span<const float> spectra,
                        std::span<const std::uint8_t> mask);
  /// Adds collection `name`.
  void add_collection(const std::string& name, const Collection& collection);
  /// Adds basis `name` (float64 datasets; empty members are not written).
  void add_basis(const std::string& name, const Basis& basis);
  /// Adds BRDF grid `name` (chunked, compressed); throws InputError on NaN/Inf or a bad scale, UsageError on sizes.
  void add_grid(const std::string& name, const Grid& grid);
  /// Creates an empty extendible set of scattered BRDF samples; with variance, each value also carries its noise
  /// variance (in units squared; samples_version 2).
  void create_samples(const std::string& name, const WavelengthGrid& wavelengths, const std::string& units,
                      const Provenance& provenance, bool variance = false);
  /// Appends n samples: angles (n x 4: theta_i, phi_i, theta_o, phi_o in radians), values (n x B) and, exactly when
  /// the samples were created with a variance, variances (n x B, finite and >= 0).
  void append_samples(const std::string& name, std::span<const double> angles, std::span<const float> values,
                      std::span<const float> variance = {});
  /// Creates coefficient map `name` for the height x width pixels of `image` on `basis` (all its k rows; a copy is
  /// stored with the map), chunked by chunk_rows whole rows; rows are then written by write_coefficient_rows.
  void create_coefficients(const std::string& name, const CoefficientsInfo& info, const Basis& basis);
  /// Writes rows [y0, y0 + rows) of map `name`: coefficients (rows x width x k) and mask (rows x width, 1 = valid);
  /// masked pixels are stored as zeros. InputError on a non-finite coefficient at a valid pixel.
  void write_coefficient_rows(const std::string& name, std::size_t y0, std::size_t rows,
                              std::span<const float> coefficients, std::span<const std::uint8_t> mask);
  /// Adds record `name` of `kind` (one of layout::kKinds other than the kinds above, e.g. "acquire") in its own data
  /// file, for other libraries' object kinds; replaces an existing object only when options().replace.
  void add_record(const std::string& kind, const std::string& name, const Record& record);
  /// Adds prior `name` (store/prior.h) with importer "prior build" in its provenance.
  void add_prior(const std::string& name, const PriorTables& prior);
  /// Removes object `name` of `kind` on commit; InputError if the store has no such object.
  void remove(const std::string& kind, const std::string& name);
  /// Makes every change visible at the store's path at once (waiting for other writers' commits, never for their
  /// work); InputError when another writer committed an object of the same name meanwhile (and replace is off).
  void commit();
  /// Objects that commit() removed or replaced and the bytes it reclaimed (valid after commit).
  const layout::Reclaimed& reclaimed() const { return reclaimed_; }

  std::string label() const { return target_.filename().string(); }
  const WriteOptions& options() const { return options_; }
  /// Whether objects begun from now on may replace committed objects of their name (each keeps the value it began
  /// with).
  void set_replace(bool replace) { options_.replace = replace; }

 private:
  /// The open data file of object (kind, name), started by begin() in this transaction; UsageError otherwise.
  std::int64_t object_file(const std::string& kind, const std::string& name, const std::string& hint) const;
  /// Validates and claims (kind, name) and creates its data file; returns the file.
  std::int64_t begin(const std::string& kind, const std::string& name, const std::string& what);
  std::filesystem::path target_;
  WriteOptions options_;
  std::unique_ptr<WriterState> state_;
  layout::Reclaimed reclaimed_;
};

/// (kind, name) of the object `spec` names in `store`: "kind/name" (kind singular or plural, e.g. image/scene) or a
/// name that only one kind uses; InputError naming the candidates otherwise.
std::pair<std::string, std::string> resolve_object(const Store& store, const std::string& spec);
/// Bytes the store occupies: the root plus every data file it references (each counted once).
std::uint64_t store_bytes(const Store& store);

/// One problem found by check(): what is wrong, naming the object or file.
struct Problem {
  std::string what;
};
/// Verifies every object's data file of the store at `path` against its recorded size and checksum, and the root's
/// links against the index; returns the problems (empty when clean). InputError for a format-1 store.
std::vector<Problem> check(const std::filesystem::path& path);
/// Reclaims the space of removed and replaced objects no reader can still see and of abandoned transactions.
layout::Reclaimed collect_garbage(const std::filesystem::path& path);
/// Converts a format-1 store at `path` in place, as one transaction (a hard link, no copy, where the file system
/// allows); InputError when it is not a format-1 store.
void upgrade(const std::filesystem::path& path);

/// Validates an object name: 1-255 chars of [A-Za-z0-9_.+-], not starting with '.'; throws UsageError.
void validate_name(const std::string& name, const std::string& kind);
/// Current UTC time as ISO 8601 ("2026-11-22T02:25:19Z").
std::string utc_now();
/// Test hook: after `n` more chunk writes, the next one fails as a full disk would (-1 disables).
void inject_write_failure_after(long long n);

}  // namespace specula::store
