#include "specula/store/io/nbrdf.h"

#include <hdf5.h>

#include <cmath>
#include <string>

#include "specula/core/error.h"
#include "specula/store/h5.h"

namespace specula::store {
namespace {

h5::Id open_file(const std::filesystem::path& path, const std::string& ctx) {
  h5::quiet_errors();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(ctx + ": no such file");
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    throw InputError(ctx + ": not an HDF5 file (an NBRDF is Keras HDF5 weights)");
  }
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    const std::string lib = h5::last_error();
    H5Eclear2(H5E_DEFAULT);
    throw InputError(ctx + ": cannot be opened as HDF5, the file is corrupt or truncated (HDF5: " + lib + ")");
  }
  return h5::Id(f);
}

std::string shape_text(const std::vector<hsize_t>& dims) {
  std::string s = "(";
  for (std::size_t i = 0; i < dims.size(); ++i) s += (i ? ", " : "") + std::to_string(dims[i]);
  return s + (dims.size() == 1 ? ",)" : ")");
}

// Dataset `name` of `file`, which must be float of exactly `expected` shape and finite.
std::vector<float> read_weights(hid_t file, const std::string& name, const std::vector<hsize_t>& expected,
                                const std::string& ctx) {
  if (!h5::exists(file, name))
    throw InputError(ctx + ": dataset '" + name + "' is missing; is this the Keras weights file of an NBRDF?");
  const std::string where = ctx + ": " + name;
  if (H5Oexists_by_name(file, name.c_str(), H5P_DEFAULT) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    throw InputError(where + ": a dangling link");
  }
  H5O_type_t type = H5O_TYPE_UNKNOWN;
  {
    h5::Id obj(H5Oopen(file, name.c_str(), H5P_DEFAULT));
    if (!obj.valid()) {
      H5Eclear2(H5E_DEFAULT);
      throw InputError(where + ": cannot be opened");
    }
    type = H5Iget_type(obj) == H5I_DATASET ? H5O_TYPE_DATASET : H5O_TYPE_GROUP;
  }
  if (type != H5O_TYPE_DATASET) throw InputError(where + ": is not a dataset");
  h5::Id ds(h5::check(H5Dopen2(file, name.c_str(), H5P_DEFAULT), where, "cannot open"));
  h5::Id dtype(h5::check(H5Dget_type(ds), where, "H5Dget_type"));
  if (H5Tget_class(dtype) != H5T_FLOAT) throw InputError(where + ": is not floating point");
  std::vector<hsize_t> dims;
  try {
    dims = h5::shape(ds, where);
  } catch (const LibraryError&) {
    throw InputError(where + ": has an unreadable shape");
  }
  if (dims != expected)
    throw InputError(where + ": shape " + shape_text(dims) + " where a 6 -> 21 -> 21 -> 3 NBRDF has " +
                     shape_text(expected));
  std::size_t n = 1;
  for (const hsize_t d : dims) n *= std::size_t(d);
  std::vector<float> v(n);
  if (H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) {
    const std::string lib = h5::last_error();
    H5Eclear2(H5E_DEFAULT);
    throw InputError(where + ": cannot be read, the file is corrupt or truncated (HDF5: " + lib + ")");
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i]))
      throw InputError(where + ": weight " + std::to_string(i) + " is " + std::to_string(v[i]) +
                       "; an NBRDF's weights are finite");
  return v;
}

}  // namespace

bool is_nbrdf(const std::filesystem::path& path) {
  h5::quiet_errors();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return false;
  }
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    H5Eclear2(H5E_DEFAULT);
    return false;
  }
  const h5::Id file(f);
  return h5::exists(file, "dense_1");
}

NbrdfWeights read_nbrdf(const std::filesystem::path& path) {
  const std::string ctx = path.string();
  const h5::Id file = open_file(path, ctx);
  constexpr hsize_t in = NbrdfWeights::kInputs, hid = NbrdfWeights::kHidden, out = NbrdfWeights::kOutputs;
  NbrdfWeights w;
  try {
    w.kernel1 = read_weights(file, "dense_1/dense_1/kernel:0", {in, hid}, ctx);
    w.bias1 = read_weights(file, "dense_1/dense_1/bias:0", {hid}, ctx);
    w.kernel2 = read_weights(file, "dense_2/dense_2/kernel:0", {hid, hid}, ctx);
    w.bias2 = read_weights(file, "dense_2/dense_2/bias:0", {hid}, ctx);
    w.kernel3 = read_weights(file, "dense_3/dense_3/kernel:0", {hid, out}, ctx);
    w.bias3 = read_weights(file, "dense_3/dense_3/bias:0", {out}, ctx);
  } catch (const LibraryError& e) {
    throw InputError(std::string(e.what()));
  }
  return w;
}

}  // namespace specula::store
