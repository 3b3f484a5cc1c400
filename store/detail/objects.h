#pragma once
// Inside store/ only: the HDF5 helpers every object kind's reader and writer share, and the root file of an open
// Store. Nothing outside store/ includes this header (HDF5 stays behind store.h).
#include <hdf5.h>

#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/store/h5.h"
#include "specula/store/layout.h"
#include "specula/store/store.h"

namespace specula::store {

static_assert(std::is_same_v<hid_t, std::int64_t>, "store.h keeps HDF5 ids as std::int64_t");

/// Target bytes of one storage chunk of a new dataset.
inline constexpr std::size_t kChunkBytes = 1 << 20;
/// The MERL grid's theta_h, theta_d, phi_d extents.
inline constexpr hsize_t kGridDims[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};
/// Chunks of (1 band, 16 theta_h, 90 theta_d, 180 phi_d) float32: about 1 MiB.
inline constexpr hsize_t kGridChunkThetaH = 16;

/// The open root file of `s`, for the store's own translation units.
struct StoreAccess {
  static hid_t root(const Store& s) { return s.file_->get(); }
};

/// "a, b, c" for messages listing names ("none" when empty; the first 12 and a count beyond).
std::string join(const std::vector<std::string>& v);
/// Throws the full-disk LibraryError the test hook (inject_write_failure_after) asks for.
void maybe_fail_write(const std::string& ctx);
/// A property list of class `cls`.
h5::Id create_plist(hid_t cls, std::string_view ctx);
/// Chunked dataset creation properties, shuffle+deflate when `c` asks.
h5::Id chunked_dcpl(std::span<const hsize_t> chunk, const Compression& c, std::string_view ctx);
/// Creates group `path` (and its parents) under `loc`.
h5::Id make_group(hid_t loc, const std::string& path, std::string_view ctx);
/// Opens group `path`; InputError naming the data file when an external link's file cannot be opened.
h5::Id open_group(hid_t loc, const std::string& path, std::string_view ctx);
/// Opens dataset `path`; InputError when it is missing.
h5::Id open_dataset(hid_t loc, const std::string& path, std::string_view ctx);
/// The filters of a dataset as text ("none", "shuffle+deflate:4").
std::string compression_of(hid_t ds, std::string_view ctx);
/// Rows per chunk of a chunked dataset (0 when contiguous).
std::size_t chunk_rows_of(hid_t ds, std::string_view ctx);
/// Row/column chunk shape of an H x W x B float32 cube: about kChunkBytes, whole rows when they fit.
std::pair<hsize_t, hsize_t> image_chunk(std::size_t h, std::size_t w, std::size_t b);
/// Writes a hyperslab of `ds` from `data`.
void write_hyperslab(hid_t ds, hid_t memtype, std::span<const hsize_t> start, std::span<const hsize_t> count,
                     const void* data, const std::string& ctx);
/// Reads a hyperslab of `ds` into `data`.
void read_hyperslab(hid_t ds, hid_t memtype, std::span<const hsize_t> start, std::span<const hsize_t> count, void* data,
                    const std::string& ctx);
/// A variable-length UTF-8 string type.
h5::Id vlen_string_type(std::string_view ctx);
/// The wavelengths dataset of an object group.
WavelengthGrid read_wavelengths(hid_t group, const std::string& ctx);
/// Writes an object group's wavelengths dataset (units nm).
void write_grid(hid_t group, const WavelengthGrid& g, const std::string& ctx);
/// A non-negative integer attribute as a size.
std::size_t attr_size(hid_t obj, const std::string& name, const std::string& ctx);
/// A numeric attribute as a double; InputError when missing or not a number.
double read_double_attr(hid_t obj, const std::string& name, const std::string& ctx);
/// A copy of `v` as an Eigen vector.
Eigen::VectorXd to_vector(const std::vector<double>& v);
/// Opens the root file at `path` read-only; InputError when HDF5 cannot open it.
h5::Id open_root(const std::filesystem::path& path, const std::string& ctx);
/// The inode of the file HDF5 opened as `file`, to tell whether the root was replaced since.
std::pair<dev_t, ino_t> opened_inode(hid_t file, const std::string& ctx);
/// Writes provenance attributes (source_file, importer, specula_version, command_line, created_utc) on obj.
void write_provenance(hid_t obj, const Provenance& p, const std::string& command_line, std::string_view ctx);
/// Reads provenance attributes written by write_provenance (missing ones empty).
Provenance read_provenance(hid_t obj, std::string_view ctx);
/// The wavelengths and k x B components of a basis group (or of the copy a coefficient map keeps).
void read_components(hid_t g, const std::string& ctx, Basis& b);

namespace layout {
/// Reads the index of an open version-2 root; InputError naming ctx when it is malformed.
Index read_index(hid_t root, std::string_view ctx);
}  // namespace layout

}  // namespace specula::store
