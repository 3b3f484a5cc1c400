#include <sys/stat.h>

#include <atomic>
#include <cstdlib>
#include <string>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"
#include "specula/version.h"

namespace specula::store {
namespace {
std::atomic<long long> g_fail_after{-2};  // -2: not yet read from the environment
}  // namespace

std::string join(const std::vector<std::string>& v) {
  if (v.empty()) return "none";
  std::string s;
  for (std::size_t i = 0; i < v.size() && i < 12; ++i) s += (i ? ", " : "") + v[i];
  if (v.size() > 12) s += ", ... (" + std::to_string(v.size()) + " in all)";
  return s;
}

void maybe_fail_write(const std::string& ctx) {
  long long n = g_fail_after.load();
  if (n == -2) {
    const char* env = std::getenv("SPECULA_INJECT_WRITE_FAILURE");
    long long v = env ? std::atoll(env) : -1;
    g_fail_after.compare_exchange_strong(n, v);
    n = g_fail_after.load();
  }
  if (n < 0) return;
  if (n == 0) throw LibraryError(ctx + ": cannot write chunk: No space left on device (injected failure)");
  g_fail_after.fetch_sub(1);
}

h5::Id create_plist(hid_t cls, std::string_view ctx) { return h5::Id(h5::check(H5Pcreate(cls), ctx, "H5Pcreate")); }

h5::Id chunked_dcpl(std::span<const hsize_t> chunk, const Compression& c, std::string_view ctx) {
  h5::Id dcpl = create_plist(H5P_DATASET_CREATE, ctx);
  h5::check(H5Pset_chunk(dcpl, int(chunk.size()), chunk.data()), ctx, "H5Pset_chunk");
  if (c.kind == Compression::Kind::deflate) {
    h5::check(H5Pset_shuffle(dcpl), ctx, "H5Pset_shuffle");
    h5::check(H5Pset_deflate(dcpl, unsigned(c.level)), ctx, "H5Pset_deflate");
  }
  return dcpl;
}

h5::Id make_group(hid_t loc, const std::string& path, std::string_view ctx) {
  h5::Id lcpl = create_plist(H5P_LINK_CREATE, ctx);
  h5::check(H5Pset_create_intermediate_group(lcpl, 1), ctx, "H5Pset_create_intermediate_group");
  return h5::Id(h5::check(H5Gcreate2(loc, path.c_str(), lcpl, H5P_DEFAULT, H5P_DEFAULT), ctx, "cannot create " + path));
}

h5::Id open_group(hid_t loc, const std::string& path, std::string_view ctx) {
  const hid_t g = H5Gopen2(loc, path.c_str(), H5P_DEFAULT);
  if (g >= 0) return h5::Id(g);
  const std::string lib = h5::last_error();
  H5Eclear2(H5E_DEFAULT);
  H5L_info_t info{};
  if (H5Lget_info(loc, path.c_str(), &info, H5P_DEFAULT) >= 0 && info.type == H5L_TYPE_EXTERNAL) {
    std::vector<char> buf(info.u.val_size + 1, '\0');
    const char* file = nullptr;
    const char* object = nullptr;
    unsigned flags = 0;
    if (H5Lget_val(loc, path.c_str(), buf.data(), buf.size(), H5P_DEFAULT) >= 0 &&
        H5Lunpack_elink_val(buf.data(), info.u.val_size, &flags, &file, &object) >= 0 && file)
      throw InputError(std::string(ctx) + ": its data file " + file +
                       " cannot be opened (missing or corrupt); `specula check` lists what is damaged (HDF5: " + lib +
                       ")");
  }
  H5Eclear2(H5E_DEFAULT);
  throw LibraryError(std::string(ctx) + ": cannot open " + path + ": " + lib);
}

h5::Id open_dataset(hid_t loc, const std::string& path, std::string_view ctx) {
  if (!h5::exists(loc, path)) throw InputError(std::string(ctx) + ": dataset '" + path + "' is missing");
  return h5::Id(h5::check(H5Dopen2(loc, path.c_str(), H5P_DEFAULT), ctx, "cannot open " + path));
}

std::string compression_of(hid_t ds, std::string_view ctx) {
  h5::Id dcpl(h5::check(H5Dget_create_plist(ds), ctx, "H5Dget_create_plist"));
  const int n = H5Pget_nfilters(dcpl);
  std::string s;
  for (int i = 0; i < n; ++i) {
    unsigned flags = 0, values[8];
    std::size_t nvalues = 8;
    char name[64] = {0};
    const H5Z_filter_t f = H5Pget_filter2(dcpl, unsigned(i), &flags, &nvalues, values, sizeof name, name, nullptr);
    if (f == H5Z_FILTER_SHUFFLE)
      s += s.empty() ? "shuffle" : "+shuffle";
    else if (f == H5Z_FILTER_DEFLATE)
      s += (s.empty() ? "deflate:" : "+deflate:") + std::to_string(nvalues ? values[0] : 0);
    else
      s += (s.empty() ? "" : "+") + std::string(name);
  }
  return s.empty() ? "none" : s;
}

std::size_t chunk_rows_of(hid_t ds, std::string_view ctx) {
  h5::Id dcpl(h5::check(H5Dget_create_plist(ds), ctx, "H5Dget_create_plist"));
  if (H5Pget_layout(dcpl) != H5D_CHUNKED) return 0;
  hsize_t dims[8] = {0};
  h5::check(H5Pget_chunk(dcpl, 8, dims), ctx, "H5Pget_chunk");
  return std::size_t(dims[0]);
}

std::pair<hsize_t, hsize_t> image_chunk(std::size_t h, std::size_t w, std::size_t b) {
  const std::size_t row_bytes = w * b * sizeof(float);
  if (row_bytes >= kChunkBytes) return {1, hsize_t(std::max<std::size_t>(1, kChunkBytes / (b * sizeof(float))))};
  return {hsize_t(std::min(h, std::max<std::size_t>(1, kChunkBytes / row_bytes))), hsize_t(w)};
}

void write_hyperslab(hid_t ds, hid_t memtype, std::span<const hsize_t> start, std::span<const hsize_t> count,
                     const void* data, const std::string& ctx) {
  h5::Id fspace(h5::check(H5Dget_space(ds), ctx, "H5Dget_space"));
  h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr), ctx,
            "H5Sselect_hyperslab");
  h5::Id mspace(h5::check(H5Screate_simple(int(count.size()), count.data(), nullptr), ctx, "H5Screate_simple"));
  maybe_fail_write(ctx);
  h5::check(H5Dwrite(ds, memtype, mspace, fspace, H5P_DEFAULT, data), ctx, "cannot write data");
}

void read_hyperslab(hid_t ds, hid_t memtype, std::span<const hsize_t> start, std::span<const hsize_t> count, void* data,
                    const std::string& ctx) {
  h5::Id fspace(h5::check(H5Dget_space(ds), ctx, "H5Dget_space"));
  h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr), ctx,
            "H5Sselect_hyperslab");
  h5::Id mspace(h5::check(H5Screate_simple(int(count.size()), count.data(), nullptr), ctx, "H5Screate_simple"));
  h5::check(H5Dread(ds, memtype, mspace, fspace, H5P_DEFAULT, data), ctx, "cannot read data");
}

h5::Id vlen_string_type(std::string_view ctx) {
  h5::Id t(h5::check(H5Tcopy(H5T_C_S1), ctx, "H5Tcopy"));
  h5::check(H5Tset_size(t, H5T_VARIABLE), ctx, "H5Tset_size");
  h5::check(H5Tset_cset(t, H5T_CSET_UTF8), ctx, "H5Tset_cset");
  return t;
}

WavelengthGrid read_wavelengths(hid_t group, const std::string& ctx) {
  return WavelengthGrid(h5::read_vector(group, "wavelengths", ctx), ctx + ": wavelengths");
}

void write_grid(hid_t group, const WavelengthGrid& g, const std::string& ctx) {
  h5::write_vector(group, "wavelengths", g.values(), ctx);
  h5::Id ds(h5::check(H5Dopen2(group, "wavelengths", H5P_DEFAULT), ctx, "cannot open wavelengths"));
  h5::write_attr(ds, "units", std::string_view("nm"), ctx);
}

std::size_t attr_size(hid_t obj, const std::string& name, const std::string& ctx) {
  const long long v = h5::read_int_attr(obj, name, ctx);
  if (v < 0) throw InputError(ctx + ": attribute '" + name + "' is negative (" + std::to_string(v) + ")");
  return std::size_t(v);
}

double read_double_attr(hid_t obj, const std::string& name, const std::string& ctx) {
  if (!h5::has_attr(obj, name)) throw InputError(ctx + ": attribute '" + name + "' is missing");
  h5::Id attr(h5::check(H5Aopen(obj, name.c_str(), H5P_DEFAULT), ctx, "cannot open attribute " + name));
  h5::Id type(h5::check(H5Aget_type(attr), ctx, "H5Aget_type"));
  if (H5Tget_class(type) != H5T_FLOAT && H5Tget_class(type) != H5T_INTEGER)
    throw InputError(ctx + ": attribute '" + name + "' is not a number");
  double v = 0;
  h5::check(H5Aread(attr, H5T_NATIVE_DOUBLE, &v), ctx, "cannot read attribute " + name);
  return v;
}

Eigen::VectorXd to_vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), Eigen::Index(v.size()));
}

void inject_write_failure_after(long long n) { g_fail_after.store(n); }

void write_provenance(hid_t obj, const Provenance& p, const std::string& command_line, std::string_view ctx) {
  h5::write_attr(obj, "source_file", std::string_view(p.source_file), ctx);
  h5::write_attr(obj, "importer", std::string_view(p.importer), ctx);
  h5::write_attr(obj, "specula_version", std::string_view(SPECULA_VERSION), ctx);
  h5::write_attr(obj, "command_line", std::string_view(p.command_line.empty() ? command_line : p.command_line), ctx);
  h5::write_attr(obj, "created_utc", std::string_view(p.created_utc.empty() ? utc_now() : p.created_utc), ctx);
}

Provenance read_provenance(hid_t obj, std::string_view ctx) {
  Provenance p;
  auto get = [&](const char* name) { return h5::has_attr(obj, name) ? h5::read_string_attr(obj, name, ctx) : ""; };
  p.source_file = get("source_file");
  p.importer = get("importer");
  p.command_line = get("command_line");
  p.created_utc = get("created_utc");
  return p;
}

h5::Id open_root(const std::filesystem::path& path, const std::string& ctx) {
  h5::Id fapl = create_plist(H5P_FILE_ACCESS, ctx);
  h5::check(H5Pset_cache(fapl, 0, 521, 16 << 20, 1.0), ctx, "H5Pset_cache");
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  if (f < 0) {
    const std::string lib = h5::last_error();
    H5Eclear2(H5E_DEFAULT);
    throw InputError(ctx + ": cannot be opened as HDF5, the file is corrupt or truncated (HDF5: " + lib + ")");
  }
  return h5::Id(f);
}

std::pair<dev_t, ino_t> opened_inode(hid_t file, const std::string& ctx) {
  void* handle = nullptr;
  h5::check(H5Fget_vfd_handle(file, H5P_DEFAULT, &handle), ctx, "H5Fget_vfd_handle");
  struct stat st {};
  if (!handle || ::fstat(*static_cast<int*>(handle), &st) != 0) throw LibraryError(ctx + ": cannot stat the open root");
  return {st.st_dev, st.st_ino};
}

void read_components(hid_t g, const std::string& ctx, Basis& b) {
  b.wavelengths = read_wavelengths(g, ctx);
  b.components = h5::read_matrix(g, "components", ctx);
  if (b.components.cols() != Eigen::Index(b.wavelengths.size()))
    throw InputError(ctx + ": components have " + std::to_string(b.components.cols()) + " bands, wavelengths " +
                     std::to_string(b.wavelengths.size()));
}

}  // namespace specula::store
