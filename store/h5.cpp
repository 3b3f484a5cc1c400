#include "specula/store/h5.h"

#include <mutex>

#include "specula/core/error.h"

namespace specula::store::h5 {
namespace {

herr_t walk_innermost(unsigned n, const H5E_error2_t* err, void* data) {
  auto* out = static_cast<std::string*>(data);
  if (n == 0 && err->desc) *out = err->desc;
  return 0;
}

#if H5_VERSION_GE(1, 12, 0)
using LinkInfo = H5L_info2_t;
#define SPECULA_H5LITERATE H5Literate2
#else
using LinkInfo = H5L_info_t;
#define SPECULA_H5LITERATE H5Literate
#endif

herr_t collect_link(hid_t, const char* name, const LinkInfo*, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}

std::string cat(std::string_view a, std::string_view b) {
  std::string s(a);
  s += ": ";
  s += b;
  return s;
}

}  // namespace

void quiet_errors() {
  static std::once_flag once;
  std::call_once(once, [] { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); });
}

std::string last_error() {
  std::string msg;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, walk_innermost, &msg);
  return msg;
}

hid_t check(hid_t value, std::string_view context, std::string_view what) {
  if (value >= 0) return value;
  std::string msg = cat(context, what);
  const std::string lib = last_error();
  H5Eclear2(H5E_DEFAULT);
  if (!lib.empty()) msg += " (HDF5: " + lib + ")";
  throw LibraryError(msg);
}

bool exists(hid_t loc, const std::string& name) {
  // Check each path component so that a missing parent is not an error.
  std::size_t pos = 0;
  while (true) {
    const std::size_t slash = name.find('/', pos + 1);
    const std::string prefix = name.substr(0, slash);
    if (!prefix.empty() && prefix != "/") {
      const htri_t r = H5Lexists(loc, prefix.c_str(), H5P_DEFAULT);
      if (r <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return false;
      }
    }
    if (slash == std::string::npos) return true;
    pos = slash;
  }
}

std::vector<std::string> list(hid_t loc, const std::string& group) {
  std::vector<std::string> names;
  if (!exists(loc, group)) return names;
  Id g(check(H5Gopen2(loc, group.c_str(), H5P_DEFAULT), group, "cannot open group"));
  check(SPECULA_H5LITERATE(g, H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_link, &names), group, "cannot list group");
  return names;
}

bool has_attr(hid_t obj, const std::string& name) {
  const htri_t r = H5Aexists(obj, name.c_str());
  if (r < 0) H5Eclear2(H5E_DEFAULT);
  return r > 0;
}

namespace {
Id replace_attr(hid_t obj, const std::string& name, hid_t type, hid_t space, std::string_view ctx) {
  if (has_attr(obj, name)) check(H5Adelete(obj, name.c_str()), ctx, "cannot replace attribute " + name);
  return Id(check(H5Acreate2(obj, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT), ctx,
                  "cannot create attribute " + name));
}
}  // namespace

void write_attr(hid_t obj, const std::string& name, std::string_view value, std::string_view ctx) {
  Id type(check(H5Tcopy(H5T_C_S1), ctx, "H5Tcopy"));
  check(H5Tset_size(type, H5T_VARIABLE), ctx, "H5Tset_size");
  check(H5Tset_cset(type, H5T_CSET_UTF8), ctx, "H5Tset_cset");
  Id space(check(H5Screate(H5S_SCALAR), ctx, "H5Screate"));
  Id attr = replace_attr(obj, name, type, space, ctx);
  const std::string copy(value);
  const char* p = copy.c_str();
  check(H5Awrite(attr, type, &p), ctx, "cannot write attribute " + name);
}

void write_attr(hid_t obj, const std::string& name, long long value, std::string_view ctx) {
  Id space(check(H5Screate(H5S_SCALAR), ctx, "H5Screate"));
  Id attr = replace_attr(obj, name, H5T_STD_I64LE, space, ctx);
  check(H5Awrite(attr, H5T_NATIVE_LLONG, &value), ctx, "cannot write attribute " + name);
}

void write_attr(hid_t obj, const std::string& name, double value, std::string_view ctx) {
  Id space(check(H5Screate(H5S_SCALAR), ctx, "H5Screate"));
  Id attr = replace_attr(obj, name, H5T_IEEE_F64LE, space, ctx);
  check(H5Awrite(attr, H5T_NATIVE_DOUBLE, &value), ctx, "cannot write attribute " + name);
}

std::string read_string_attr(hid_t obj, const std::string& name, std::string_view ctx) {
  if (!has_attr(obj, name)) throw InputError(cat(ctx, "attribute '" + name + "' is missing"));
  Id attr(check(H5Aopen(obj, name.c_str(), H5P_DEFAULT), ctx, "cannot open attribute " + name));
  Id type(check(H5Aget_type(attr), ctx, "H5Aget_type"));
  if (H5Tget_class(type) != H5T_STRING) throw InputError(cat(ctx, "attribute '" + name + "' is not a string"));
  if (H5Tis_variable_str(type) > 0) {
    Id mem(check(H5Tcopy(H5T_C_S1), ctx, "H5Tcopy"));
    check(H5Tset_size(mem, H5T_VARIABLE), ctx, "H5Tset_size");
    check(H5Tset_cset(mem, H5Tget_cset(type)), ctx, "H5Tset_cset");
    char* p = nullptr;
    check(H5Aread(attr, mem, &p), ctx, "cannot read attribute " + name);
    std::string s = p ? p : "";
    Id space(H5Aget_space(attr));
    H5free_memory(p);
    return s;
  }
  const std::size_t n = H5Tget_size(type);
  std::string s(n, '\0');
  check(H5Aread(attr, type, s.data()), ctx, "cannot read attribute " + name);
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
  return s;
}

long long read_int_attr(hid_t obj, const std::string& name, std::string_view ctx) {
  if (!has_attr(obj, name)) throw InputError(cat(ctx, "attribute '" + name + "' is missing"));
  Id attr(check(H5Aopen(obj, name.c_str(), H5P_DEFAULT), ctx, "cannot open attribute " + name));
  Id type(check(H5Aget_type(attr), ctx, "H5Aget_type"));
  if (H5Tget_class(type) != H5T_INTEGER) throw InputError(cat(ctx, "attribute '" + name + "' is not an integer"));
  long long v = 0;
  check(H5Aread(attr, H5T_NATIVE_LLONG, &v), ctx, "cannot read attribute " + name);
  return v;
}

std::vector<hsize_t> shape(hid_t dataset, std::string_view ctx) {
  Id space(check(H5Dget_space(dataset), ctx, "H5Dget_space"));
  const int rank = H5Sget_simple_extent_ndims(space);
  check(rank, ctx, "cannot read dataset rank");
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  check(H5Sget_simple_extent_dims(space, dims.data(), nullptr), ctx, "cannot read dataset shape");
  return dims;
}

void write_vector(hid_t loc, const std::string& name, std::span<const double> v, std::string_view ctx) {
  const hsize_t n = v.size();
  Id space(check(H5Screate_simple(1, &n, nullptr), ctx, "H5Screate_simple"));
  Id ds(check(H5Dcreate2(loc, name.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
              "cannot create dataset " + name));
  if (n) check(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx, "cannot write " + name);
}

std::vector<double> read_vector(hid_t loc, const std::string& name, std::string_view ctx) {
  if (!exists(loc, name)) throw InputError(cat(ctx, "dataset '" + name + "' is missing"));
  Id ds(check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), ctx, "cannot open " + name));
  auto dims = shape(ds, ctx);
  if (dims.size() != 1) throw InputError(cat(ctx, "dataset '" + name + "' is not one-dimensional"));
  std::vector<double> v(dims[0]);
  if (!v.empty())
    check(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx, "cannot read " + name);
  return v;
}

void write_matrix(hid_t loc, const std::string& name, const Eigen::MatrixXd& m, std::string_view ctx) {
  const hsize_t dims[2] = {hsize_t(m.rows()), hsize_t(m.cols())};
  h5::Id space(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id ds(h5::check(H5Dcreate2(loc, name.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
                      "cannot create " + name));
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rm = m;
  if (m.size())
    h5::check(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, rm.data()), ctx, "cannot write " + name);
}

Eigen::MatrixXd read_matrix(hid_t loc, const std::string& name, std::string_view ctx) {
  if (!h5::exists(loc, name)) throw InputError(std::string(ctx) + ": dataset '" + name + "' is missing");
  h5::Id ds(h5::check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), ctx, "cannot open " + name));
  const auto dims = h5::shape(ds, ctx);
  if (dims.size() != 2) throw InputError(std::string(ctx) + ": dataset '" + name + "' is not two-dimensional");
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rm{Eigen::Index(dims[0]),
                                                                            Eigen::Index(dims[1])};
  if (rm.size())
    h5::check(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, rm.data()), ctx, "cannot read " + name);
  return rm;
}

}  // namespace specula::store::h5
