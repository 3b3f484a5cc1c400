#pragma once
// The checked HDF5 wrapper: every HDF5 C call in specula goes through check(), which throws
// specula::LibraryError carrying HDF5's own error-stack message, and ids are owned by Id.
#include <hdf5.h>

#include <Eigen/Core>

#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula::store::h5 {

/// Silences HDF5's automatic error printing (errors are thrown instead); idempotent.
void quiet_errors();
/// Throws LibraryError("<context>: <what>: <HDF5 message>") if value < 0, else returns it.
hid_t check(hid_t value, std::string_view context, std::string_view what);
/// The innermost message of HDF5's current error stack ("" when empty).
std::string last_error();

/// An owned HDF5 identifier of any kind, closed with H5Idec_ref on destruction.
class Id {
 public:
  Id() = default;
  explicit Id(hid_t id) : id_(id) {}
  Id(const Id& o) : id_(o.id_) {
    if (id_ > 0) H5Iinc_ref(id_);
  }
  Id(Id&& o) noexcept : id_(o.id_) { o.id_ = H5I_INVALID_HID; }
  Id& operator=(Id o) noexcept {
    std::swap(id_, o.id_);
    return *this;
  }
  ~Id() {
    if (id_ > 0 && H5Iis_valid(id_) > 0) H5Idec_ref(id_);
  }
  hid_t get() const { return id_; }
  operator hid_t() const { return id_; }
  bool valid() const { return id_ > 0; }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

/// True if `name` is a link in `loc` (no error if absent).
bool exists(hid_t loc, const std::string& name);
/// Names of the links in group `group` of `loc`, in name order; empty if the group is absent.
std::vector<std::string> list(hid_t loc, const std::string& group);

/// Writes a scalar variable-length UTF-8 string attribute (replacing one of the same name).
void write_attr(hid_t obj, const std::string& name, std::string_view value, std::string_view ctx);
/// Writes a scalar int64 attribute.
void write_attr(hid_t obj, const std::string& name, long long value, std::string_view ctx);
/// Writes a scalar double attribute.
void write_attr(hid_t obj, const std::string& name, double value, std::string_view ctx);
/// Reads a string attribute (fixed or variable length); throws InputError naming ctx if absent or not a string.
std::string read_string_attr(hid_t obj, const std::string& name, std::string_view ctx);
/// Reads an integer attribute; throws InputError naming ctx if absent or not numeric.
long long read_int_attr(hid_t obj, const std::string& name, std::string_view ctx);
/// True if obj has attribute name.
bool has_attr(hid_t obj, const std::string& name);

/// Shape of a dataset.
std::vector<hsize_t> shape(hid_t dataset, std::string_view ctx);
/// Writes a whole 1-D float64 dataset `name` under `loc`.
void write_vector(hid_t loc, const std::string& name, std::span<const double> v, std::string_view ctx);
/// Reads a whole 1-D numeric dataset as float64.
std::vector<double> read_vector(hid_t loc, const std::string& name, std::string_view ctx);
/// Writes a whole 2-D float64 dataset `name` under `loc` (row-major on disk).
void write_matrix(hid_t loc, const std::string& name, const Eigen::MatrixXd& m, std::string_view ctx);
/// Reads a whole 2-D numeric dataset as float64; throws InputError naming ctx if absent or not 2-D.
Eigen::MatrixXd read_matrix(hid_t loc, const std::string& name, std::string_view ctx);

}  // namespace specula::store::h5
