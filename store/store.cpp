#include "specula/store/store.h"

#include <omp.h>
#include <libdeflate.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <optional>
#include <set>
#include <sstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "specula/core/parallel.h"
#include "specula/core/atomic_file.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/core/text.h"
#include "specula/version.h"

namespace specula::store {
namespace {

constexpr std::size_t kChunkBytes = 1 << 20;
std::atomic<long long> g_fail_after{-2};  // -2: not yet read from the environment

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
                       " cannot be opened (missing or corrupt); `specula check` lists what is damaged (HDF5: " + lib + ")");
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
    if (f == H5Z_FILTER_SHUFFLE) s += s.empty() ? "shuffle" : "+shuffle";
    else if (f == H5Z_FILTER_DEFLATE) s += (s.empty() ? "deflate:" : "+deflate:") + std::to_string(nvalues ? values[0] : 0);
    else s += (s.empty() ? "" : "+") + std::string(name);
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

// Row/column chunk shape of an H x W x B float32 cube: about kChunkBytes, whole rows when they fit.
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

void read_hyperslab(hid_t ds, hid_t memtype, std::span<const hsize_t> start, std::span<const hsize_t> count,
                    void* data, const std::string& ctx) {
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

}  // namespace

namespace {
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

constexpr hsize_t kGridDims[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};
// Chunks of (1 band, 16 theta_h, 90 theta_d, 180 phi_d) float32: about 1 MiB.
constexpr hsize_t kGridChunkThetaH = 16;

Eigen::VectorXd to_vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), Eigen::Index(v.size()));
}
}  // namespace

Compression Compression::parse(std::string_view spec) {
  Compression c;
  if (spec == "none") {
    c.kind = Kind::none;
    return c;
  }
  if (spec == "deflate") return c;
  if (spec.starts_with("deflate:") && spec.size() == 9 && spec[8] >= '1' && spec[8] <= '9') {
    c.level = spec[8] - '0';
    return c;
  }
  throw UsageError("compression '" + std::string(spec) + "': use none, deflate or deflate:LEVEL with LEVEL 1-9");
}

std::string Compression::describe() const {
  return kind == Kind::none ? "none" : "shuffle+deflate:" + std::to_string(level);
}

void validate_name(const std::string& name, const std::string& kind) {
  bool ok = !name.empty() && name.size() <= 255 && name[0] != '.';
  for (char c : name)
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' || c == '+');
  if (!ok)
    throw UsageError(kind + " name '" + name +
                     "' is not allowed: use 1-255 characters of letters, digits, '_', '-', '.', '+', not starting with '.'");
}

std::string utc_now() {
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
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

// ---------------------------------------------------------------- Store

struct Store::Snapshot {
  layout::Index index;
  layout::ReaderLock lock;
};

namespace {
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

// The inode of the file HDF5 opened as `file`, to tell whether the root was replaced since.
std::pair<dev_t, ino_t> opened_inode(hid_t file, const std::string& ctx) {
  void* handle = nullptr;
  h5::check(H5Fget_vfd_handle(file, H5P_DEFAULT, &handle), ctx, "H5Fget_vfd_handle");
  struct stat st {};
  if (!handle || ::fstat(*static_cast<int*>(handle), &st) != 0) throw LibraryError(ctx + ": cannot stat the open root");
  return {st.st_dev, st.st_ino};
}
}  // namespace

Store Store::open(const std::filesystem::path& path) {
  h5::quiet_errors();
  Store s;
  s.path_ = path;
  const std::string ctx = s.label();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(ctx + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw InputError(ctx + ": is a directory, not a store file");
  // A reader pins the generation it opened; a commit between opening the root and pinning it makes it try again.
  for (int attempt = 0;; ++attempt) {
    const htri_t is = H5Fis_hdf5(path.c_str());
    if (is <= 0) {
      H5Eclear2(H5E_DEFAULT);
      throw InputError(ctx + ": not an HDF5 file, so not a specula store (create one with `specula import` or `specula synth-db`)");
    }
    h5::Id f = open_root(path, ctx);
    if (!h5::has_attr(f, "specula_format") || h5::read_string_attr(f, "specula_format", ctx) != kFormatName)
      throw InputError(ctx + ": an HDF5 file but not a specula store (no specula_format = \"" + kFormatName +
                       "\" attribute on /); create stores with `specula import` or `specula synth-db`");
    s.version_ = h5::read_int_attr(f, "format_version", ctx);
    if (s.version_ > kFormatVersion)
      throw InputError(ctx + ": store format version " + std::to_string(s.version_) + " is newer than this specula (" +
                       SPECULA_VERSION + ") reads (up to " + std::to_string(kFormatVersion) + "); upgrade specula");
    if (s.version_ < 1) throw InputError(ctx + ": invalid store format version " + std::to_string(s.version_));
    if (s.version_ == 1) {
      s.file_ = std::make_shared<h5::Id>(std::move(f));
      return s;
    }
    auto snap = std::make_shared<Snapshot>();
    snap->index = layout::read_index(f, ctx);
    snap->lock = layout::ReaderLock(layout::data_dir(path, snap->index), snap->index.generation);
    struct stat now {};
    const auto opened = opened_inode(f, ctx);
    if (attempt < 100 && (::stat(path.c_str(), &now) != 0 || now.st_dev != opened.first || now.st_ino != opened.second))
      continue;
    s.file_ = std::make_shared<h5::Id>(std::move(f));
    s.snapshot_ = std::move(snap);
    return s;
  }
}

bool Store::stale() const {
  if (!file_) return false;
  const auto opened = opened_inode(*file_, label());
  struct stat now {};
  return ::stat(path_.c_str(), &now) != 0 || now.st_dev != opened.first || now.st_ino != opened.second;
}

const layout::Index& Store::index() const {
  static const layout::Index none;
  return snapshot_ ? snapshot_->index : none;
}

std::vector<std::string> Store::images() const { return h5::list(file(), "/images"); }
std::vector<std::string> Store::collections() const { return h5::list(file(), "/collections"); }
std::vector<std::string> Store::samples() const { return h5::list(file(), "/samples"); }
std::vector<std::string> Store::grids() const { return h5::list(file(), "/grids"); }
std::vector<std::string> Store::bases() const { return h5::list(file(), "/bases"); }
std::vector<std::string> Store::coefficients() const { return h5::list(file(), "/coefficients"); }

ImageInfo Store::image_info(const std::string& name) const {
  const std::string path = "/images/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no image '" + name + "' (images: " + join(images()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  ImageInfo info;
  info.name = name;
  h5::Id cube = open_dataset(g, "cube", ctx);
  auto dims = h5::shape(cube, ctx);
  if (dims.size() != 3) throw InputError(ctx + "/cube: expected 3 dimensions (height, width, bands)");
  info.height = dims[0];
  info.width = dims[1];
  info.bands = dims[2];
  info.wavelengths = read_wavelengths(g, ctx);
  if (info.wavelengths.size() != info.bands)
    throw InputError(ctx + ": cube has " + std::to_string(info.bands) + " bands but wavelengths lists " +
                     std::to_string(info.wavelengths.size()));
  info.has_fwhm = h5::exists(g, "fwhm");
  info.units = h5::has_attr(g, "units") ? h5::read_string_attr(g, "units", ctx) : "unknown";
  info.valid_pixels = attr_size(g, "valid_pixels", ctx);
  info.chunk_rows = chunk_rows_of(cube, ctx);
  info.compression = compression_of(cube, ctx);
  info.provenance = read_provenance(g, ctx);
  h5::Id mask = open_dataset(g, "mask", ctx);
  auto mdims = h5::shape(mask, ctx);
  if (mdims.size() != 2 || mdims[0] != dims[0] || mdims[1] != dims[1])
    throw InputError(ctx + "/mask: shape does not match the cube's height x width");
  return info;
}

CollectionInfo Store::collection_info(const std::string& name) const {
  const std::string path = "/collections/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no collection '" + name + "' (collections: " + join(collections()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  CollectionInfo info;
  info.name = name;
  h5::Id ds = open_dataset(g, "spectra", ctx);
  auto dims = h5::shape(ds, ctx);
  if (dims.size() != 2) throw InputError(ctx + "/spectra: expected 2 dimensions (spectra, bands)");
  info.size = dims[0];
  info.bands = dims[1];
  info.wavelengths = read_wavelengths(g, ctx);
  if (info.wavelengths.size() != info.bands) throw InputError(ctx + ": spectra and wavelengths disagree on band count");
  info.units = h5::has_attr(g, "units") ? h5::read_string_attr(g, "units", ctx) : "unknown";
  info.chunk_rows = chunk_rows_of(ds, ctx);
  info.provenance = read_provenance(g, ctx);
  return info;
}

SamplesInfo Store::samples_info(const std::string& name) const {
  const std::string path = "/samples/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no samples '" + name + "' (samples: " + join(samples()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  SamplesInfo info;
  info.name = name;
  h5::Id values = open_dataset(g, "values", ctx);
  auto dims = h5::shape(values, ctx);
  h5::Id angles = open_dataset(g, "angles", ctx);
  auto adims = h5::shape(angles, ctx);
  if (dims.size() != 2 || adims.size() != 2 || adims[1] != 4 || adims[0] != dims[0])
    throw InputError(ctx + ": angles must be N x 4 and values N x B with the same N");
  info.size = dims[0];
  info.bands = dims[1];
  info.wavelengths = read_wavelengths(g, ctx);
  if (info.wavelengths.size() != info.bands) throw InputError(ctx + ": values and wavelengths disagree on band count");
  info.units = h5::has_attr(g, "units") ? h5::read_string_attr(g, "units", ctx) : "unknown";
  info.chunk_rows = chunk_rows_of(values, ctx);
  info.provenance = read_provenance(g, ctx);
  return info;
}

Cube Store::read_image(const std::string& name) const {
  const ImageInfo info = image_info(name);
  const std::string ctx = label() + ": /images/" + name;
  h5::Id g = open_group(file(), "/images/" + name, ctx);
  Cube c;
  c.resize(info.height, info.width, info.bands);
  c.wavelengths = info.wavelengths;
  c.units = info.units;
  c.provenance = info.provenance;
  if (info.has_fwhm) c.fwhm = h5::read_vector(g, "fwhm", ctx);
  h5::Id cube = open_dataset(g, "cube", ctx);
  h5::check(H5Dread(cube, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, c.data.data()), ctx, "cannot read cube");
  c.mask.resize(info.height * info.width);
  h5::Id mask = open_dataset(g, "mask", ctx);
  h5::check(H5Dread(mask, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, c.mask.data()), ctx, "cannot read mask");
  return c;
}

bool Store::read_pixel(const std::string& name, std::size_t x, std::size_t y, std::span<float> out) const {
  const ImageInfo info = image_info(name);
  const std::string ctx = label() + ": /images/" + name;
  if (x >= info.width || y >= info.height)
    throw UsageError(ctx + ": pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is outside the " +
                     std::to_string(info.width) + " x " + std::to_string(info.height) + " image");
  if (out.size() != info.bands)
    throw UsageError(ctx + ": a pixel has " + std::to_string(info.bands) + " bands, the buffer " + std::to_string(out.size()));
  h5::Id g = open_group(file(), "/images/" + name, ctx);
  {
    h5::Id cube = open_dataset(g, "cube", ctx);
    h5::Id space(h5::check(H5Dget_space(cube), ctx, "cannot get the cube's dataspace"));
    const hsize_t start[3] = {y, x, 0}, count[3] = {1, 1, info.bands};
    h5::check(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), ctx, "cannot select a pixel");
    h5::Id memory(h5::check(H5Screate_simple(1, &count[2], nullptr), ctx, "cannot create a dataspace"));
    h5::check(H5Dread(cube, H5T_NATIVE_FLOAT, memory, space, H5P_DEFAULT, out.data()), ctx, "cannot read a pixel");
  }
  h5::Id mask = open_dataset(g, "mask", ctx);
  h5::Id space(h5::check(H5Dget_space(mask), ctx, "cannot get the mask's dataspace"));
  const hsize_t start[2] = {y, x}, count[2] = {1, 1};
  h5::check(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), ctx, "cannot select a pixel");
  const hsize_t one = 1;
  h5::Id memory(h5::check(H5Screate_simple(1, &one, nullptr), ctx, "cannot create a dataspace"));
  std::uint8_t valid = 0;
  h5::check(H5Dread(mask, H5T_NATIVE_UINT8, memory, space, H5P_DEFAULT, &valid), ctx, "cannot read the mask");
  return valid != 0;
}

Collection Store::read_collection(const std::string& name) const {
  const CollectionInfo info = collection_info(name);
  const std::string ctx = label() + ": /collections/" + name;
  h5::Id g = open_group(file(), "/collections/" + name, ctx);
  Collection c;
  c.wavelengths = info.wavelengths;
  c.units = info.units;
  c.provenance = info.provenance;
  c.values.resize(info.size * info.bands);
  h5::Id ds = open_dataset(g, "spectra", ctx);
  if (!c.values.empty())
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, c.values.data()), ctx, "cannot read spectra");
  h5::Id names = open_dataset(g, "names", ctx);
  if (h5::shape(names, ctx) != std::vector<hsize_t>{info.size})
    throw InputError(ctx + "/names: expected one name per spectrum");
  std::vector<char*> raw(info.size, nullptr);
  h5::Id type = vlen_string_type(ctx);
  if (info.size) h5::check(H5Dread(names, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()), ctx, "cannot read names");
  c.names.reserve(info.size);
  for (char* p : raw) c.names.emplace_back(p ? p : "");
  if (info.size) {
    h5::Id space(h5::check(H5Dget_space(names), ctx, "H5Dget_space"));
#if H5_VERSION_GE(1, 12, 0)
    H5Treclaim(type, space, H5P_DEFAULT, raw.data());
#else
    H5Dvlen_reclaim(type, space, H5P_DEFAULT, raw.data());
#endif
  }
  return c;
}

namespace {
// The wavelengths and k x B components of a basis group (or of the copy a coefficient map keeps).
void read_components(hid_t g, const std::string& ctx, Basis& b) {
  b.wavelengths = read_wavelengths(g, ctx);
  b.components = h5::read_matrix(g, "components", ctx);
  if (b.components.cols() != Eigen::Index(b.wavelengths.size()))
    throw InputError(ctx + ": components have " + std::to_string(b.components.cols()) + " bands, wavelengths " +
                     std::to_string(b.wavelengths.size()));
}
}  // namespace

Basis Store::read_basis(const std::string& name) const {
  const std::string path = "/bases/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no basis '" + name + "' (bases: " + join(bases()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  Basis b;
  b.method = h5::read_string_attr(g, "method", ctx);
  b.n = std::uint64_t(std::max(0LL, h5::read_int_attr(g, "n", ctx)));
  b.source = h5::has_attr(g, "source") ? h5::read_string_attr(g, "source", ctx) : "";
  b.provenance = read_provenance(g, ctx);
  read_components(g, ctx, b);
  auto vec = [&](const char* nm) {
    return h5::exists(g, nm) ? to_vector(h5::read_vector(g, nm, ctx)) : Eigen::VectorXd();
  };
  b.mean = vec("mean");
  b.eigenvalues = vec("eigenvalues");
  b.explained_variance_ratio = vec("explained_variance_ratio");
  b.weights = vec("weights");
  if (h5::exists(g, "covariance")) b.covariance = h5::read_matrix(g, "covariance", ctx);
  if (h5::exists(g, "second_moment")) b.second_moment = h5::read_matrix(g, "second_moment", ctx);
  if (b.mean.size() && b.mean.size() != b.components.cols())
    throw InputError(ctx + ": mean has " + std::to_string(b.mean.size()) + " entries for " +
                     std::to_string(b.components.cols()) + " bands");
  return b;
}

CoefficientsInfo Store::coefficients_info(const std::string& name) const {
  const std::string path = "/coefficients/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no coefficient map '" + name + "' (coefficient maps: " + join(coefficients()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  CoefficientsInfo info;
  info.name = name;
  info.image = h5::read_string_attr(g, "image", ctx);
  info.basis = h5::read_string_attr(g, "basis", ctx);
  info.method = h5::read_string_attr(g, "method", ctx);
  if (info.method != "pca" && info.method != "nmf")
    throw InputError(ctx + ": method '" + info.method + "' is neither pca nor nmf");
  info.valid_pixels = attr_size(g, "valid_pixels", ctx);
  info.provenance = read_provenance(g, ctx);
  h5::Id ds = open_dataset(g, "coefficients", ctx);
  const auto dims = h5::shape(ds, ctx);
  if (dims.size() != 3 || dims[2] == 0) throw InputError(ctx + "/coefficients: expected 3 dimensions (height, width, k)");
  info.height = dims[0];
  info.width = dims[1];
  info.k = dims[2];
  info.chunk_rows = chunk_rows_of(ds, ctx);
  info.compression = compression_of(ds, ctx);
  h5::Id mask = open_dataset(g, "mask", ctx);
  const auto mdims = h5::shape(mask, ctx);
  if (mdims.size() != 2 || mdims[0] != dims[0] || mdims[1] != dims[1])
    throw InputError(ctx + "/mask: shape does not match the coefficients' height x width");
  h5::Id components = open_dataset(g, "components", ctx);
  const auto cdims = h5::shape(components, ctx);
  if (cdims.size() != 2 || cdims[0] != dims[2])
    throw InputError(ctx + "/components: expected " + std::to_string(dims[2]) + " rows, one per coefficient");
  return info;
}

Basis Store::coefficients_basis(const std::string& name) const {
  const CoefficientsInfo info = coefficients_info(name);
  const std::string ctx = label() + ": /coefficients/" + name;
  h5::Id g = open_group(file(), "/coefficients/" + name, ctx);
  Basis b;
  b.method = info.method;
  b.source = "image " + info.image;
  b.provenance = info.provenance;
  read_components(g, ctx, b);
  if (h5::exists(g, "mean")) b.mean = to_vector(h5::read_vector(g, "mean", ctx));
  if (info.method == "pca" && b.mean.size() != b.components.cols())
    throw InputError(ctx + ": a PCA map needs a mean of " + std::to_string(b.components.cols()) + " bands");
  return b;
}

void Store::read_coefficient_rows(const std::string& name, std::size_t y0, std::size_t rows,
                                  std::span<float> coefficients, std::span<std::uint8_t> mask) const {
  const CoefficientsInfo info = coefficients_info(name);
  const std::string ctx = label() + ": /coefficients/" + name;
  if (rows == 0 || y0 + rows > info.height)
    throw UsageError(ctx + ": rows " + std::to_string(y0) + " to " + std::to_string(y0 + rows) + " are outside its " +
                     std::to_string(info.height) + " rows");
  if (coefficients.size() != rows * info.width * info.k || (!mask.empty() && mask.size() != rows * info.width))
    throw UsageError(ctx + ": buffers do not match " + std::to_string(rows) + " rows of " + std::to_string(info.width) +
                     " x " + std::to_string(info.k));
  h5::Id g = open_group(file(), "/coefficients/" + name, ctx);
  h5::Id ds = open_dataset(g, "coefficients", ctx);
  const hsize_t start[3] = {y0, 0, 0}, count[3] = {rows, info.width, info.k};
  read_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, coefficients.data(), ctx);
  if (mask.empty()) return;
  h5::Id mds = open_dataset(g, "mask", ctx);
  read_hyperslab(mds, H5T_NATIVE_UINT8, std::span<const hsize_t>(start, 2), std::span<const hsize_t>(count, 2),
                 mask.data(), ctx);
}

GridInfo Store::grid_info(const std::string& name) const {
  const std::string path = "/grids/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(file(), path))
    throw InputError(label() + ": no grid '" + name + "' (grids: " + join(grids()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(file(), path, ctx);
  GridInfo info;
  info.name = name;
  h5::Id ds = open_dataset(g, "brdf", ctx);
  const auto dims = h5::shape(ds, ctx);
  if (dims.size() != 4 || dims[1] != kGridDims[0] || dims[2] != kGridDims[1] || dims[3] != kGridDims[2])
    throw InputError(ctx + "/brdf: expected shape (bands, 90, 90, 180), the MERL layout");
  info.bands = dims[0];
  info.wavelengths = read_wavelengths(g, ctx);
  if (info.wavelengths.size() != info.bands)
    throw InputError(ctx + ": brdf has " + std::to_string(info.bands) + " bands but wavelengths lists " +
                     std::to_string(info.wavelengths.size()));
  info.scale = read_double_attr(g, "scale", ctx);
  if (!std::isfinite(info.scale) || info.scale <= 0)
    throw InputError(ctx + ": attribute 'scale' is " + num(info.scale) + "; it must be finite and positive");
  info.units = h5::has_attr(g, "units") ? h5::read_string_attr(g, "units", ctx) : "unknown";
  info.compression = compression_of(ds, ctx);
  info.provenance = read_provenance(g, ctx);
  return info;
}

Grid Store::read_grid(const std::string& name) const {
  const GridInfo info = grid_info(name);
  const std::string ctx = label() + ": /grids/" + name;
  h5::Id g = open_group(file(), "/grids/" + name, ctx);
  Grid grid;
  grid.wavelengths = info.wavelengths;
  grid.scale = info.scale;
  grid.units = info.units;
  grid.provenance = info.provenance;
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  h5::Id ds = open_dataset(g, "brdf", ctx);
  if (!grid.brdf.empty())
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, grid.brdf.data()), ctx, "cannot read brdf");
  return grid;
}

void Store::read_samples(const std::string& name, std::size_t first, std::size_t count, std::span<double> angles,
                         std::span<float> values) const {
  const SamplesInfo info = samples_info(name);
  const std::string ctx = label() + ": /samples/" + name;
  const bool want_angles = !angles.empty(), want_values = !values.empty();
  if (first > info.size || count > info.size - first || (want_angles && angles.size() != count * 4) ||
      (want_values && values.size() != count * info.bands))
    throw UsageError(ctx + ": read_samples range or buffer sizes are wrong");
  if (count == 0) return;
  h5::Id g = open_group(file(), "/samples/" + name, ctx);
  const hsize_t s2[2] = {first, 0}, ca[2] = {count, 4}, cv[2] = {count, info.bands};
  if (want_angles) read_hyperslab(open_dataset(g, "angles", ctx), H5T_NATIVE_DOUBLE, s2, ca, angles.data(), ctx);
  if (want_values) read_hyperslab(open_dataset(g, "values", ctx), H5T_NATIVE_FLOAT, s2, cv, values.data(), ctx);
}

// ---------------------------------------------------------------- StoreWriter

struct StoreWriter::State {
  struct Pending {
    std::string kind, name, file;  // file: relative to the data directory
    h5::Id h5;                     // open until the object is complete
    std::size_t rows_expected = 0, rows_written = 0;  // images filled by write_image_rows
    std::vector<bool> row_done;
    std::uint64_t valid = 0;
    bool replace = false;  // may replace a committed object of its name (the options' replace when begun)
  };
  std::filesystem::path root, data;
  layout::Index base;  // the committed state when the transaction began
  bool created_data = false;
  std::optional<layout::Transaction> tx;
  std::vector<Pending> pending;
  std::vector<std::pair<std::string, std::string>> removals;
  bool committed = false;

  Pending* find(std::string_view kind, std::string_view name) {
    for (auto& p : pending)
      if (p.kind == kind && p.name == name) return &p;
    return nullptr;
  }
  void close(std::string_view kind, std::string_view name) {
    if (Pending* p = find(kind, name)) p->h5 = h5::Id();
  }
  void drop(std::string_view kind, std::string_view name) {
    for (auto it = pending.begin(); it != pending.end(); ++it)
      if (it->kind == kind && it->name == name) {
        it->h5 = h5::Id();
        H5Eclear2(H5E_DEFAULT);
        std::error_code ec;
        std::filesystem::remove(data / it->file, ec);
        pending.erase(it);
        return;
      }
  }
};

StoreWriter::StoreWriter(const std::filesystem::path& path, WriteOptions options)
    : target_(path), options_(std::move(options)), state_(std::make_unique<State>()) {
  h5::quiet_errors();
  const std::string ctx = label();
  State& st = *state_;
  st.root = path;
  if (std::filesystem::exists(path)) {
    const Store s = Store::open(path);  // validates: a specula store of a version we can write
    if (s.format_version() < 2)
      throw InputError(ctx + ": store format version " + std::to_string(s.format_version()) +
                       " (one file) is read-only in this specula; convert it in place with `specula upgrade " +
                       path.string() + "` (no copy of the data)");
    st.base = s.index();
    st.data = s.data_dir();
    layout::claim_data_dir(path, st.data);
  } else {
    const auto dir = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
    if (path.filename().empty()) throw UsageError("store path '" + path.string() + "' names no file");
    if (!std::filesystem::is_directory(dir)) throw InputError(path.string() + ": directory " + dir.string() + " does not exist");
    st.data = layout::default_data_dir(path);
    st.base.data_dir = st.data.filename().string();
    st.base.created_utc = utc_now();
    st.created_data = !std::filesystem::exists(st.data);
  }
  layout::create_directories_synced(st.data / "objects");
  st.tx.emplace(st.data);
  if (st.created_data) layout::claim_data_dir(path, st.data);
}

StoreWriter::~StoreWriter() {
  if (!state_) return;
  State& st = *state_;
  for (auto& p : st.pending) p.h5 = h5::Id();
  H5Eclear2(H5E_DEFAULT);
  std::error_code ec;
  if (!st.committed)
    for (const auto& p : st.pending) std::filesystem::remove(st.data / p.file, ec);
  if (st.tx) st.tx->end();
  // A store that was never created leaves no directory behind (rmdir fails harmlessly when others use it).
  if (!st.committed && st.created_data && !std::filesystem::exists(st.root)) {
    for (const auto kind : layout::kKinds) ::rmdir((st.data / "objects" / std::string(kind)).c_str());
    ::rmdir((st.data / "objects").c_str());
    ::rmdir((st.data / "tx").c_str());
    ::rmdir(st.data.c_str());
  }
}

hid_t StoreWriter::begin(const std::string& kind, const std::string& name, const std::string& what) {
  validate_name(name, what);
  if (!state_ || state_->committed) throw UsageError(label() + ": the transaction is already committed");
  State& st = *state_;
  if (st.find(kind, name)) {
    if (!options_.replace)
      throw InputError(label() + ": " + what + " '" + name + "' is written twice in one transaction");
    st.drop(kind, name);
  }
  if (st.base.find(kind, name) && !options_.replace)
    throw InputError(label() + ": " + what + " '" + name + "' exists already; choose another name or allow replacing it");
  const std::string rel = layout::object_file(kind, name, st.tx->id());
  layout::create_directories_synced(st.data / "objects" / kind);
  const std::string ctx = label() + ": /" + kind + "/" + name;
  h5::Id fapl = create_plist(H5P_FILE_ACCESS, ctx);
  h5::check(H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG), ctx, "H5Pset_fclose_degree");
  h5::check(H5Pset_cache(fapl, 0, 521, 16 << 20, 1.0), ctx, "H5Pset_cache");
  const auto file = st.data / rel;
  h5::Id f(h5::check(H5Fcreate(file.c_str(), H5F_ACC_EXCL, H5P_DEFAULT, fapl), ctx, "cannot create " + file.string()));
  layout::crash_point("object-created");
  h5::write_attr(f, "specula_format", std::string_view("specula-object"), ctx);
  h5::write_attr(f, "format_version", kFormatVersion, ctx);
  h5::write_attr(f, "kind", std::string_view(kind), ctx);
  h5::write_attr(f, "name", std::string_view(name), ctx);
  h5::write_attr(f, "transaction", std::string_view(st.tx->id()), ctx);
  st.pending.push_back({kind, name, rel, f});
  st.pending.back().replace = options_.replace;
  return f.get();
}

hid_t StoreWriter::object_file(const std::string& kind, const std::string& name, const std::string& hint) const {
  State::Pending* p = state_ ? state_->find(kind, name) : nullptr;
  if (!p || !p->h5.valid()) throw UsageError(label() + ": /" + kind + "/" + name + ": " + hint);
  return p->h5.get();
}

h5::Id StoreWriter::create_group(const std::string& kind, const std::string& name) {
  if (!layout::is_kind(kind) || kind == "images")
    throw UsageError(label() + ": '" + kind + "' is not a group for create_group (use acquire, or the add_ functions)");
  const std::string path = "/" + kind + "/" + name;
  return make_group(begin(kind, name, kind), path, label() + ": " + path);
}

void StoreWriter::remove(const std::string& kind, const std::string& name) {
  if (!layout::is_kind(kind)) throw UsageError(label() + ": '" + kind + "' is not a kind of object");
  if (!state_->base.find(kind, name))
    throw InputError(label() + ": no " + kind + " '" + name + "' to remove");
  state_->removals.emplace_back(kind, name);
}

namespace {
// HDF5's shuffle then deflate filters applied to `elems` floats with libdeflate (the same zlib stream, several times
// faster) into dst; returns the compressed size (0 on failure). Thread-safe.
std::size_t shuffle_deflate(const float* plain, std::size_t elems, int level, std::vector<unsigned char>& dst) {
  thread_local std::vector<unsigned char> shuffled;
  const std::size_t bytes = elems * sizeof(float);
  shuffled.resize(bytes);
  const auto* src = reinterpret_cast<const unsigned char*>(plain);
  for (std::size_t e = 0; e < elems; ++e)
    for (std::size_t byte = 0; byte < 4; ++byte) shuffled[byte * elems + e] = src[e * 4 + byte];
  thread_local std::unique_ptr<libdeflate_compressor, void (*)(libdeflate_compressor*)> compressor(
      nullptr, libdeflate_free_compressor);
  thread_local int compressor_level = -1;
  if (!compressor || compressor_level != level) {
    compressor.reset(libdeflate_alloc_compressor(level));
    compressor_level = level;
  }
  if (!compressor) return 0;
  dst.resize(libdeflate_zlib_compress_bound(compressor.get(), bytes));
  return libdeflate_zlib_compress(compressor.get(), shuffled.data(), bytes, dst.data(), dst.size());
}

// Compresses `chunks` chunks in parallel batches, fill(k, plain) giving chunk k's values and offset(k) its
// position, and hands them to H5Dwrite_chunk in order.
template <class Fill, class Offset>
void write_chunks_deflated(hid_t ds, std::size_t chunks, std::size_t chunk_elems, int level, const std::string& ctx,
                           Fill&& fill, Offset&& offset) {
  const std::size_t batch = std::size_t(std::max(1, omp_get_max_threads())) * 4;
  std::vector<std::vector<unsigned char>> out(batch);
  std::vector<std::size_t> out_size(batch);
  Progress progress("writing " + ctx, chunks);
  for (std::size_t first = 0; first < chunks; first += batch) {
    check_interrupt();
    const std::size_t n = std::min(batch, chunks - first);
    parallel_for(n, [] { return std::vector<float>(); }, [&](std::size_t j, std::vector<float>& plain) {
      plain.assign(chunk_elems, 0.0f);
      fill(first + j, plain);
      out_size[j] = shuffle_deflate(plain.data(), chunk_elems, level, out[j]);
      if (out_size[j] == 0) throw LibraryError(ctx + ": libdeflate failed to compress a chunk");
    });
    for (std::size_t j = 0; j < n; ++j) {
      const auto at = offset(first + j);
      maybe_fail_write(ctx);
      h5::check(H5Dwrite_chunk(ds, H5P_DEFAULT, 0, at.data(), out_size[j], out[j].data()), ctx, "cannot write chunk");
    }
    progress.advance(n);
  }
}

// Writes rows [y0, y0 + h) of a shuffle+deflate cube chunk by chunk (write_chunks_deflated); y0 and h are whole
// chunk rows (h may end at the cube's last row); the bytes are what HDF5's own filters would store. Pixels whose mask
// byte is 0 (mask may be null) are stored as zeros.
void write_rows_deflated(hid_t ds, const float* data, const std::uint8_t* mask, std::size_t y0, std::size_t h,
                         std::size_t w, std::size_t b, std::size_t ch, std::size_t cw, int level, const std::string& ctx) {
  const std::size_t row_chunks = (h + ch - 1) / ch, col_chunks = (w + cw - 1) / cw;
  write_chunks_deflated(
      ds, row_chunks * col_chunks, ch * cw * b, level, ctx,
      [&](std::size_t k, std::vector<float>& plain) {
        const std::size_t r = k / col_chunks, c = k % col_chunks;
        const std::size_t ry = r * ch, x0 = c * cw;
        const std::size_t ny = std::min(ch, h - ry), nx = std::min(cw, w - x0);
        for (std::size_t y = 0; y < ny; ++y)
          for (std::size_t x = 0; x < nx; ++x) {
            const std::size_t p = (ry + y) * w + x0 + x;
            if (!mask || mask[p]) std::copy_n(data + p * b, b, plain.data() + (y * cw + x) * b);
          }
      },
      [&](std::size_t k) { return std::array<hsize_t, 3>{y0 + (k / col_chunks) * ch, (k % col_chunks) * cw, 0}; });
}
}  // namespace

namespace {
void write_image_objects(hid_t file, const std::string& name, const Cube& cube, std::uint64_t valid,
                         const WriteOptions& options_, const std::string& ctx);
}

void StoreWriter::add_image(const std::string& name, const Cube& cube) {
  const std::string ctx = label() + ": /images/" + name;
  const std::string src = cube.provenance.source_file.empty() ? name : cube.provenance.source_file;
  if (cube.height == 0 || cube.width == 0 || cube.bands == 0)
    throw InputError(src + ": image is empty (" + std::to_string(cube.height) + "x" + std::to_string(cube.width) + "x" +
                     std::to_string(cube.bands) + ")");
  if (cube.data.size() != cube.height * cube.width * cube.bands || (!cube.mask.empty() && cube.mask.size() != cube.height * cube.width))
    throw UsageError(ctx + ": cube buffers do not match its dimensions");
  if (cube.wavelengths.size() != cube.bands)
    throw InputError(src + ": image has " + std::to_string(cube.bands) + " bands but " +
                     std::to_string(cube.wavelengths.size()) + " wavelengths");
  if (!cube.fwhm.empty() && cube.fwhm.size() != cube.bands)
    throw InputError(src + ": " + std::to_string(cube.fwhm.size()) + " FWHM values for " + std::to_string(cube.bands) + " bands");
  // Non-finite values in valid pixels are the importer's business; here they are a hard error.
  std::uint64_t valid = 0;
  for (std::size_t p = 0; p < cube.height * cube.width; ++p) {
    if (!cube.mask.empty() && !cube.mask[p]) continue;
    ++valid;
    const float* s = cube.data.data() + p * cube.bands;
    for (std::size_t b = 0; b < cube.bands; ++b)
      if (!std::isfinite(s[b]))
        throw InputError(src + ": non-finite value at row " + std::to_string(p / cube.width) + ", column " +
                         std::to_string(p % cube.width) + ", band " + std::to_string(b) +
                         "; mask such pixels before storing (an importer's nan = mask)");
  }
  const hid_t f = begin("images", name, "image");
  try {
    write_image_objects(f, name, cube, valid, options_, ctx);
  } catch (...) {
    state_->drop("images", name);  // a later commit keeps only whole images
    throw;
  }
  state_->close("images", name);
}

namespace {
struct ImageDatasets {
  h5::Id group, cube, mask;
  hsize_t chunk_rows = 0, chunk_cols = 0;
};

// The group, cube and mask datasets of an image, chunked as docs/store-format.md says.
ImageDatasets create_image_datasets(hid_t file, const std::string& name, std::size_t height, std::size_t width,
                                    const WavelengthGrid& wavelengths, std::span<const double> fwhm,
                                    const std::string& units, const Provenance& provenance,
                                    const WriteOptions& options_, const std::string& ctx) {
  ImageDatasets d;
  d.group = make_group(file, "/images/" + name, ctx);
  h5::Id& g = d.group;
  h5::write_attr(g, "kind", std::string_view("image"), ctx);
  h5::write_attr(g, "units", std::string_view(units), ctx);
  write_provenance(g, provenance, options_.command_line, ctx);
  write_grid(g, wavelengths, ctx);
  if (!fwhm.empty()) h5::write_vector(g, "fwhm", fwhm, ctx);
  const std::size_t bands = wavelengths.size();
  std::tie(d.chunk_rows, d.chunk_cols) = image_chunk(height, width, bands);
  const hsize_t dims[3] = {height, width, bands};
  const hsize_t chunk[3] = {d.chunk_rows, d.chunk_cols, bands};
  h5::Id space(h5::check(H5Screate_simple(3, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id dcpl = chunked_dcpl(chunk, options_.compression, ctx);
  d.cube = h5::Id(h5::check(H5Dcreate2(g, "cube", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx, "cannot create cube"));
  h5::write_attr(d.cube, "axes", std::string_view("height,width,band"), ctx);
  h5::Id mspace(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id mdcpl = chunked_dcpl(std::span<const hsize_t>(chunk, 2), options_.compression, ctx);
  d.mask = h5::Id(h5::check(H5Dcreate2(g, "mask", H5T_STD_U8LE, mspace, H5P_DEFAULT, mdcpl, H5P_DEFAULT), ctx, "cannot create mask"));
  return d;
}

void write_image_objects(hid_t file, const std::string& name, const Cube& cube, std::uint64_t valid,
                         const WriteOptions& options_, const std::string& ctx) {
  const ImageDatasets d = create_image_datasets(file, name, cube.height, cube.width, cube.wavelengths, cube.fwhm,
                                                cube.units, cube.provenance, options_, ctx);
  h5::write_attr(d.group, "valid_pixels", static_cast<long long>(valid), ctx);
  const hid_t ds = d.cube, mds = d.mask;
  const std::size_t ch = d.chunk_rows, cw = d.chunk_cols;
  bool ch_written_by_chunks = false;

  if (options_.compression.kind == Compression::Kind::deflate) {
    write_rows_deflated(ds, cube.data.data(), cube.mask.empty() ? nullptr : cube.mask.data(), 0, cube.height, cube.width,
                        cube.bands, ch, cw, options_.compression.level, ctx);
    ch_written_by_chunks = true;
  }
  // Write by chunk rows; masked pixels are stored as zeros so the cube holds only finite numbers.
  std::vector<float> rows;
  std::vector<std::uint8_t> mrows;
  Progress progress("writing " + name, cube.height);
  for (std::size_t y0 = 0; y0 < cube.height; y0 += ch) {
    check_interrupt();
    const std::size_t n = std::min<std::size_t>(ch, cube.height - y0);
    const std::size_t px = n * cube.width;
    rows.assign(cube.data.begin() + std::ptrdiff_t(y0 * cube.width * cube.bands),
                cube.data.begin() + std::ptrdiff_t((y0 + n) * cube.width * cube.bands));
    mrows.assign(px, 1);
    if (!cube.mask.empty()) {
      for (std::size_t p = 0; p < px; ++p) {
        mrows[p] = cube.mask[y0 * cube.width + p] ? 1 : 0;
        if (!mrows[p]) std::fill_n(rows.data() + p * cube.bands, cube.bands, 0.0f);
      }
    }
    const hsize_t start[3] = {y0, 0, 0}, count[3] = {n, cube.width, cube.bands};
    if (!ch_written_by_chunks) write_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, rows.data(), ctx);
    write_hyperslab(mds, H5T_NATIVE_UINT8, std::span<const hsize_t>(start, 2), std::span<const hsize_t>(count, 2),
                    mrows.data(), ctx);
    progress.advance(n);
  }
}
}  // namespace

void StoreWriter::add_collection(const std::string& name, const Collection& col) {
  const std::string ctx = label() + ": /collections/" + name;
  const std::string src = col.provenance.source_file.empty() ? name : col.provenance.source_file;
  const std::size_t n = col.size(), b = col.bands();
  if (n == 0 || b == 0) throw InputError(src + ": collection is empty");
  if (col.values.size() != n * b) throw UsageError(ctx + ": values do not match names x bands");
  for (std::size_t i = 0; i < n * b; ++i)
    if (!std::isfinite(col.values[i]))
      throw InputError(src + ": non-finite value in spectrum '" + col.names[i / b] + "' at " +
                       std::to_string(col.wavelengths[i % b]) + " nm");
  h5::Id g = make_group(begin("collections", name, "collection"), "/collections/" + name, ctx);
  h5::write_attr(g, "kind", std::string_view("collection"), ctx);
  h5::write_attr(g, "units", std::string_view(col.units), ctx);
  write_provenance(g, col.provenance, options_.command_line, ctx);
  write_grid(g, col.wavelengths, ctx);

  const hsize_t dims[2] = {n, b};
  const hsize_t chunk[2] = {std::min<hsize_t>(n, std::max<hsize_t>(1, kChunkBytes / (b * sizeof(float)))), b};
  h5::Id space(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id dcpl = chunked_dcpl(chunk, options_.compression, ctx);
  h5::Id ds(h5::check(H5Dcreate2(g, "spectra", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx, "cannot create spectra"));
  for (hsize_t r0 = 0; r0 < n; r0 += chunk[0]) {
    check_interrupt();
    const hsize_t start[2] = {r0, 0}, count[2] = {std::min<hsize_t>(chunk[0], n - r0), b};
    write_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, col.values.data() + r0 * b, ctx);
  }
  const hsize_t ndims[1] = {n};
  h5::Id nspace(h5::check(H5Screate_simple(1, ndims, nullptr), ctx, "H5Screate_simple"));
  h5::Id type = vlen_string_type(ctx);
  h5::Id nds(h5::check(H5Dcreate2(g, "names", type, nspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx, "cannot create names"));
  std::vector<const char*> ptrs;
  for (const auto& s : col.names) ptrs.push_back(s.c_str());
  h5::check(H5Dwrite(nds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()), ctx, "cannot write names");
}


void StoreWriter::add_basis(const std::string& name, const Basis& basis) {
  const std::string ctx = label() + ": /bases/" + name;
  const auto b = Eigen::Index(basis.bands());
  if (b == 0 || basis.components.cols() != b || basis.components.rows() == 0)
    throw UsageError(ctx + ": a basis needs k x B components on its wavelength grid");
  auto check_len = [&](const Eigen::VectorXd& v, const char* what) {
    if (v.size() != 0 && v.size() != b && std::string(what) != "weights")
      throw UsageError(ctx + ": " + what + " has " + std::to_string(v.size()) + " entries for " + std::to_string(b) + " bands");
  };
  check_len(basis.mean, "mean");
  check_len(basis.eigenvalues, "eigenvalues");
  check_len(basis.explained_variance_ratio, "explained_variance_ratio");
  if (!basis.components.allFinite()) throw InputError(ctx + ": basis has non-finite components");
  h5::Id g = make_group(begin("bases", name, "basis"), "/bases/" + name, ctx);
  h5::write_attr(g, "kind", std::string_view("basis"), ctx);
  h5::write_attr(g, "method", std::string_view(basis.method), ctx);
  h5::write_attr(g, "n", static_cast<long long>(basis.n), ctx);
  h5::write_attr(g, "source", std::string_view(basis.source), ctx);
  write_provenance(g, basis.provenance, options_.command_line, ctx);
  write_grid(g, basis.wavelengths, ctx);
  h5::write_matrix(g, "components", basis.components, ctx);
  auto vec = [&](const char* nm, const Eigen::VectorXd& v) {
    if (v.size()) h5::write_vector(g, nm, std::span<const double>(v.data(), std::size_t(v.size())), ctx);
  };
  vec("mean", basis.mean);
  vec("eigenvalues", basis.eigenvalues);
  vec("explained_variance_ratio", basis.explained_variance_ratio);
  vec("weights", basis.weights);
  if (basis.covariance.size()) h5::write_matrix(g, "covariance", basis.covariance, ctx);
  if (basis.second_moment.size()) h5::write_matrix(g, "second_moment", basis.second_moment, ctx);
}

void StoreWriter::add_grid(const std::string& name, const Grid& grid) {
  const std::string ctx = label() + ": /grids/" + name;
  const std::string src = grid.provenance.source_file.empty() ? name : grid.provenance.source_file;
  const std::size_t b = grid.bands();
  if (b == 0) throw UsageError(ctx + ": a grid needs at least one wavelength");
  if (grid.brdf.size() != b * brdf::kMerlCells)
    throw UsageError(ctx + ": brdf holds " + std::to_string(grid.brdf.size()) + " values; " + std::to_string(b) +
                     " bands x 90 x 90 x 180 need " + std::to_string(b * brdf::kMerlCells));
  if (!std::isfinite(grid.scale) || grid.scale <= 0)
    throw InputError(src + ": grid scale is " + num(grid.scale) + "; it must be finite and positive");
  for (std::size_t i = 0; i < grid.brdf.size(); ++i)
    if (!std::isfinite(grid.brdf[i]))
      throw InputError(src + ": non-finite BRDF value at band " + std::to_string(i / brdf::kMerlCells) + ", cell " +
                       std::to_string(i % brdf::kMerlCells) + "; use a negative value for cells without data");
  const hid_t f = begin("grids", name, "grid");
  try {
    h5::Id g = make_group(f, "/grids/" + name, ctx);
    h5::write_attr(g, "kind", std::string_view("grid"), ctx);
    h5::write_attr(g, "units", std::string_view(grid.units), ctx);
    h5::write_attr(g, "scale", grid.scale, ctx);
    h5::write_attr(g, "layout", std::string_view("merl"), ctx);
    write_provenance(g, grid.provenance, options_.command_line, ctx);
    write_grid(g, grid.wavelengths, ctx);
    const hsize_t dims[4] = {b, kGridDims[0], kGridDims[1], kGridDims[2]};
    const hsize_t chunk[4] = {1, kGridChunkThetaH, kGridDims[1], kGridDims[2]};
    h5::Id space(h5::check(H5Screate_simple(4, dims, nullptr), ctx, "H5Screate_simple"));
    h5::Id dcpl = chunked_dcpl(chunk, options_.compression, ctx);
    h5::Id ds(h5::check(H5Dcreate2(g, "brdf", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                        "cannot create brdf"));
    h5::write_attr(ds, "axes", std::string_view("band,theta_h,theta_d,phi_d"), ctx);
    if (options_.compression.kind == Compression::Kind::deflate) {
      // Chunks of kGridChunkThetaH theta_h rows of one band, compressed on every thread.
      const std::size_t row = std::size_t(kGridDims[1] * kGridDims[2]);
      const std::size_t per_band = (kGridDims[0] + kGridChunkThetaH - 1) / kGridChunkThetaH;
      write_chunks_deflated(
          ds, b * per_band, kGridChunkThetaH * row, options_.compression.level, ctx,
          [&](std::size_t k, std::vector<float>& plain) {
            const std::size_t band = k / per_band, h0 = (k % per_band) * kGridChunkThetaH;
            const std::size_t rows = std::min<std::size_t>(kGridChunkThetaH, kGridDims[0] - h0);
            std::copy_n(grid.brdf.data() + band * brdf::kMerlCells + h0 * row, rows * row, plain.data());
          },
          [&](std::size_t k) {
            return std::array<hsize_t, 4>{k / per_band, (k % per_band) * kGridChunkThetaH, 0, 0};
          });
    } else {
      Progress progress("writing " + name, b);
      for (hsize_t k = 0; k < b; ++k) {
        check_interrupt();
        const hsize_t start[4] = {k, 0, 0, 0}, count[4] = {1, kGridDims[0], kGridDims[1], kGridDims[2]};
        write_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, grid.brdf.data() + k * brdf::kMerlCells, ctx);
        progress.advance();
      }
    }
  } catch (...) {
    state_->drop("grids", name);
    throw;
  }
  state_->close("grids", name);
}

void StoreWriter::create_samples(const std::string& name, const WavelengthGrid& wavelengths, const std::string& units,
                                 const Provenance& provenance) {
  const std::string ctx = label() + ": /samples/" + name;
  if (wavelengths.empty()) throw UsageError(ctx + ": samples need at least one wavelength");
  h5::Id g = make_group(begin("samples", name, "samples"), "/samples/" + name, ctx);
  h5::write_attr(g, "kind", std::string_view("samples"), ctx);
  h5::write_attr(g, "units", std::string_view(units), ctx);
  write_provenance(g, provenance, options_.command_line, ctx);
  write_grid(g, wavelengths, ctx);
  const hsize_t b = wavelengths.size();
  const hsize_t adims0[2] = {0, 4}, vdims0[2] = {0, b};
  const hsize_t amax[2] = {H5S_UNLIMITED, 4}, vmax[2] = {H5S_UNLIMITED, b};
  const hsize_t achunk[2] = {8192, 4};
  const hsize_t vchunk[2] = {std::max<hsize_t>(1, kChunkBytes / (b * sizeof(float))), b};
  h5::Id aspace(h5::check(H5Screate_simple(2, adims0, amax), ctx, "H5Screate_simple"));
  h5::Id vspace(h5::check(H5Screate_simple(2, vdims0, vmax), ctx, "H5Screate_simple"));
  h5::Id adcpl = chunked_dcpl(achunk, options_.compression, ctx);
  h5::Id vdcpl = chunked_dcpl(vchunk, options_.compression, ctx);
  h5::Id a(h5::check(H5Dcreate2(g, "angles", H5T_IEEE_F64LE, aspace, H5P_DEFAULT, adcpl, H5P_DEFAULT), ctx, "cannot create angles"));
  h5::write_attr(a, "columns", std::string_view("theta_i,phi_i,theta_o,phi_o"), ctx);
  h5::write_attr(a, "units", std::string_view("rad"), ctx);
  h5::Id v(h5::check(H5Dcreate2(g, "values", H5T_IEEE_F32LE, vspace, H5P_DEFAULT, vdcpl, H5P_DEFAULT), ctx, "cannot create values"));
}

void StoreWriter::append_samples(const std::string& name, std::span<const double> angles, std::span<const float> values) {
  const std::string ctx = label() + ": /samples/" + name;
  h5::Id g = open_group(object_file("samples", name, "create_samples first"), "/samples/" + name, ctx);
  h5::Id a = open_dataset(g, "angles", ctx);
  h5::Id v = open_dataset(g, "values", ctx);
  const auto vd = h5::shape(v, ctx);
  const hsize_t b = vd[1];
  if (angles.size() % 4 != 0 || values.size() != angles.size() / 4 * b)
    throw UsageError(ctx + ": append_samples needs n x 4 angles and n x " + std::to_string(b) + " values");
  const hsize_t n = angles.size() / 4;
  for (std::size_t i = 0; i < angles.size(); ++i)
    if (!std::isfinite(angles[i])) throw InputError(ctx + ": non-finite angle in sample " + std::to_string(vd[0] + i / 4));
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i])) throw InputError(ctx + ": non-finite value in sample " + std::to_string(vd[0] + i / b));
  if (n == 0) return;
  const hsize_t new_a[2] = {vd[0] + n, 4}, new_v[2] = {vd[0] + n, b};
  h5::check(H5Dset_extent(a, new_a), ctx, "cannot extend angles");
  h5::check(H5Dset_extent(v, new_v), ctx, "cannot extend values");
  const hsize_t start[2] = {vd[0], 0}, ca[2] = {n, 4}, cv[2] = {n, b};
  write_hyperslab(a, H5T_NATIVE_DOUBLE, start, ca, angles.data(), ctx);
  write_hyperslab(v, H5T_NATIVE_FLOAT, start, cv, values.data(), ctx);
}

void StoreWriter::create_coefficients(const std::string& name, const CoefficientsInfo& info, const Basis& basis) {
  const std::string ctx = label() + ": /coefficients/" + name;
  const std::size_t k = basis.k(), b = basis.bands();
  if (info.height == 0 || info.width == 0 || k == 0 || b == 0 || basis.components.cols() != Eigen::Index(b))
    throw UsageError(ctx + ": a coefficient map needs a non-empty image and a k x B basis on its wavelength grid");
  if (basis.method != "pca" && basis.method != "nmf")
    throw UsageError(ctx + ": basis method '" + basis.method + "' is neither pca nor nmf");
  if (basis.method == "pca" && basis.mean.size() != Eigen::Index(b))
    throw UsageError(ctx + ": a PCA basis needs its mean (" + std::to_string(b) + " bands)");
  if (!basis.components.allFinite() || !basis.mean.allFinite()) throw InputError(ctx + ": basis has non-finite values");
  if (info.chunk_rows == 0) throw UsageError(ctx + ": chunk_rows must be at least 1");
  h5::Id g = make_group(begin("coefficients", name, "coefficient map"), "/coefficients/" + name, ctx);
  h5::write_attr(g, "kind", std::string_view("coefficients"), ctx);
  h5::write_attr(g, "image", std::string_view(info.image), ctx);
  h5::write_attr(g, "basis", std::string_view(info.basis), ctx);
  h5::write_attr(g, "method", std::string_view(basis.method), ctx);
  h5::write_attr(g, "valid_pixels", static_cast<long long>(info.valid_pixels), ctx);
  write_provenance(g, info.provenance, options_.command_line, ctx);
  write_grid(g, basis.wavelengths, ctx);
  h5::write_matrix(g, "components", basis.components, ctx);
  if (basis.method == "pca")
    h5::write_vector(g, "mean", std::span<const double>(basis.mean.data(), b), ctx);

  const hsize_t rows = std::min<hsize_t>(info.chunk_rows, info.height);
  const hsize_t dims[3] = {info.height, info.width, k}, chunk[3] = {rows, info.width, k};
  h5::Id space(h5::check(H5Screate_simple(3, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id dcpl = chunked_dcpl(chunk, options_.compression, ctx);
  h5::Id ds(h5::check(H5Dcreate2(g, "coefficients", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                      "cannot create coefficients"));
  h5::write_attr(ds, "axes", std::string_view("height,width,component"), ctx);
  h5::Id mspace(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id mdcpl = chunked_dcpl(std::span<const hsize_t>(chunk, 2), options_.compression, ctx);
  h5::Id mds(h5::check(H5Dcreate2(g, "mask", H5T_STD_U8LE, mspace, H5P_DEFAULT, mdcpl, H5P_DEFAULT), ctx,
                       "cannot create mask"));
}

void StoreWriter::write_coefficient_rows(const std::string& name, std::size_t y0, std::size_t rows,
                                         std::span<const float> coefficients, std::span<const std::uint8_t> mask) {
  const std::string path = "/coefficients/" + name, ctx = label() + ": " + path;
  h5::Id g = open_group(object_file("coefficients", name, "create the map with create_coefficients before writing rows"),
                        path, ctx);
  h5::Id ds = open_dataset(g, "coefficients", ctx);
  const auto dims = h5::shape(ds, ctx);
  const std::size_t width = dims[1], k = dims[2];
  if (rows == 0 || y0 + rows > dims[0])
    throw UsageError(ctx + ": rows " + std::to_string(y0) + " to " + std::to_string(y0 + rows) + " are outside its " +
                     std::to_string(dims[0]) + " rows");
  if (coefficients.size() != rows * width * k || mask.size() != rows * width)
    throw UsageError(ctx + ": buffers do not match " + std::to_string(rows) + " rows of " + std::to_string(width) +
                     " x " + std::to_string(k));
  std::vector<float> values(coefficients.begin(), coefficients.end());
  for (std::size_t p = 0; p < rows * width; ++p) {
    float* c = values.data() + p * k;
    if (!mask[p]) {
      std::fill_n(c, k, 0.0f);
      continue;
    }
    for (std::size_t j = 0; j < k; ++j)
      if (!std::isfinite(c[j]))
        throw InputError(ctx + ": non-finite coefficient " + std::to_string(j) + " at row " +
                         std::to_string(y0 + p / width) + ", column " + std::to_string(p % width));
  }
  std::vector<std::uint8_t> valid(rows * width);
  for (std::size_t p = 0; p < valid.size(); ++p) valid[p] = mask[p] ? 1 : 0;
  const hsize_t start[3] = {y0, 0, 0}, count[3] = {rows, width, k};
  write_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, values.data(), ctx);
  h5::Id mds = open_dataset(g, "mask", ctx);
  write_hyperslab(mds, H5T_NATIVE_UINT8, std::span<const hsize_t>(start, 2), std::span<const hsize_t>(count, 2),
                  valid.data(), ctx);
}

std::size_t StoreWriter::create_image(const std::string& name, std::size_t height, std::size_t width,
                               const WavelengthGrid& wavelengths, std::span<const double> fwhm, const std::string& units,
                               const Provenance& provenance) {
  const std::string ctx = label() + ": /images/" + name;
  const std::string src = provenance.source_file.empty() ? name : provenance.source_file;
  if (height == 0 || width == 0 || wavelengths.empty())
    throw InputError(src + ": image is empty (" + std::to_string(height) + "x" + std::to_string(width) + "x" +
                     std::to_string(wavelengths.size()) + ")");
  if (!fwhm.empty() && fwhm.size() != wavelengths.size())
    throw InputError(src + ": " + std::to_string(fwhm.size()) + " FWHM values for " + std::to_string(wavelengths.size()) + " bands");
  const hid_t f = begin("images", name, "image");
  std::size_t chunk_rows = 0;
  try {
    chunk_rows = create_image_datasets(f, name, height, width, wavelengths, fwhm, units, provenance, options_, ctx).chunk_rows;
  } catch (...) {
    state_->drop("images", name);
    throw;
  }
  State::Pending& p = *state_->find("images", name);
  p.rows_expected = height;
  p.row_done.assign(height, false);
  return chunk_rows;
}

void StoreWriter::write_image_rows(const std::string& name, std::size_t y0, std::size_t rows,
                                   std::span<const float> spectra, std::span<const std::uint8_t> mask) {
  const std::string path = "/images/" + name, ctx = label() + ": " + path;
  h5::Id g = open_group(object_file("images", name, "create the image with create_image before writing rows"), path, ctx);
  State::Pending& p = *state_->find("images", name);
  h5::Id ds = open_dataset(g, "cube", ctx);
  const auto dims = h5::shape(ds, ctx);
  const std::size_t width = dims[1], bands = dims[2];
  if (p.rows_expected == 0) throw UsageError(ctx + ": write_image_rows fills images made by create_image only");
  if (rows == 0 || y0 + rows > dims[0])
    throw UsageError(ctx + ": rows " + std::to_string(y0) + " to " + std::to_string(y0 + rows) + " are outside its " +
                     std::to_string(dims[0]) + " rows");
  if (spectra.size() != rows * width * bands || (!mask.empty() && mask.size() != rows * width))
    throw UsageError(ctx + ": buffers do not match " + std::to_string(rows) + " rows of " + std::to_string(width) +
                     " x " + std::to_string(bands));
  std::vector<float> values(spectra.begin(), spectra.end());
  std::vector<std::uint8_t> valid(rows * width, 1);
  std::uint64_t count = 0;
  for (std::size_t q = 0; q < rows * width; ++q) {
    float* s = values.data() + q * bands;
    if (!mask.empty() && !mask[q]) {
      valid[q] = 0;
      std::fill_n(s, bands, 0.0f);
      continue;
    }
    ++count;
    for (std::size_t b = 0; b < bands; ++b)
      if (!std::isfinite(s[b]))
        throw InputError(ctx + ": non-finite value at row " + std::to_string(y0 + q / width) + ", column " +
                         std::to_string(q % width) + ", band " + std::to_string(b) + "; mask such pixels before storing");
  }
  for (std::size_t y = y0; y < y0 + rows; ++y)
    if (p.row_done[y]) throw UsageError(ctx + ": row " + std::to_string(y) + " is written twice");
  const hsize_t start[3] = {y0, 0, 0}, cnt[3] = {rows, width, bands};
  const auto [ch, cw] = image_chunk(dims[0], width, bands);
  if (options_.compression.kind == Compression::Kind::deflate && y0 % ch == 0 && (rows % ch == 0 || y0 + rows == dims[0]))
    write_rows_deflated(ds, values.data(), nullptr, y0, rows, width, bands, ch, cw, options_.compression.level, ctx);
  else
    write_hyperslab(ds, H5T_NATIVE_FLOAT, start, cnt, values.data(), ctx);
  h5::Id mds = open_dataset(g, "mask", ctx);
  write_hyperslab(mds, H5T_NATIVE_UINT8, std::span<const hsize_t>(start, 2), std::span<const hsize_t>(cnt, 2),
                  valid.data(), ctx);
  for (std::size_t y = y0; y < y0 + rows; ++y) p.row_done[y] = true;
  p.rows_written += rows;
  p.valid += count;
}

void StoreWriter::commit() {
  if (!state_ || state_->committed) throw UsageError(label() + ": StoreWriter::commit called twice");
  State& st = *state_;
  const std::string ctx = label();
  // Images written row by row are complete, or the transaction is wrong.
  for (auto& p : st.pending) {
    if (p.rows_expected == 0) continue;
    if (p.rows_written != p.rows_expected)
      throw UsageError(ctx + ": /images/" + p.name + ": " + std::to_string(p.rows_written) + " of " +
                       std::to_string(p.rows_expected) + " rows written; write every row before commit");
    h5::Id g = open_group(p.h5, "/images/" + p.name, ctx);
    h5::write_attr(g, "valid_pixels", static_cast<long long>(p.valid), ctx);
  }
  // 1. Every data file complete and durable before anything points at it.
  std::vector<layout::Entry> added;
  std::set<std::string> dirs;
  for (auto& p : st.pending) {
    if (p.h5.valid()) {
      h5::check(H5Fflush(p.h5, H5F_SCOPE_GLOBAL), ctx, "cannot flush " + p.file);
      p.h5 = h5::Id();
    }
    layout::Entry e{p.kind, p.name, p.file, 0, 0, 0};
    e.crc32 = layout::file_crc32(st.data / p.file, e.bytes);
    layout::sync_path(st.data / p.file);
    dirs.insert(p.kind);
    added.push_back(std::move(e));
  }
  layout::crash_point("data-written");
  for (const auto& k : dirs) layout::sync_path(st.data / "objects" / k, true);
  layout::sync_path(st.data / "objects", true);
  { const int fd = ::open((st.data / "readers").c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, 0644); if (fd >= 0) ::close(fd); }
  layout::sync_path(st.data, true);

  // 2. Under the commit lock: merge into the state committed meanwhile.
  layout::FileLock lock(st.data / "commit.lock", true);
  layout::crash_point("locked");
  layout::Index cur;
  if (std::filesystem::exists(st.root)) {
    h5::Id f = open_root(st.root, ctx);
    if (!h5::has_attr(f, "format_version") || h5::read_int_attr(f, "format_version", ctx) != kFormatVersion)
      throw InputError(ctx + ": the store was replaced by a file of another format while this transaction ran; nothing was written");
    cur = layout::read_index(f, ctx);
    if (cur.data_dir != st.base.data_dir)
      throw InputError(ctx + ": another store was created at this path while this transaction ran; nothing was written");
  } else {
    cur = st.base;
    cur.generation = 0;
    cur.entries.clear();
  }
  const long long gen = cur.generation + 1;
  std::vector<layout::Garbage> garbage;
  auto unlink_entry = [&](std::string_view kind, std::string_view name) {
    for (auto it = cur.entries.begin(); it != cur.entries.end(); ++it)
      if (it->kind == kind && it->name == name) {
        const layout::Entry old = *it;
        cur.entries.erase(it);
        if (!cur.references(old.file)) garbage.push_back({old.file, old.generation, gen});
        return;
      }
  };
  for (const auto& [kind, name] : st.removals) unlink_entry(kind, name);
  for (auto& e : added) {
    if (cur.find(e.kind, e.name)) {
      if (!st.find(e.kind, e.name)->replace)
        throw InputError(ctx + ": " + e.kind + "/" + e.name + " was committed by another writer while this transaction ran; "
                         "nothing was written (choose another name or allow replacing it)");
      unlink_entry(e.kind, e.name);
    }
    e.generation = gen;
    cur.entries.push_back(e);
  }
  auto order = [](const layout::Entry& e) {
    return std::find(std::begin(layout::kKinds), std::end(layout::kKinds), e.kind) - std::begin(layout::kKinds);
  };
  std::sort(cur.entries.begin(), cur.entries.end(), [&](const layout::Entry& a, const layout::Entry& b) {
    return std::pair(order(a), a.name) < std::pair(order(b), b.name);
  });
  cur.generation = gen;

  // 3. The garbage list first, then the new root, renamed over the old one: the commit point.
  layout::append_garbage(st.data, garbage);
  layout::crash_point("garbage-logged");
  const std::filesystem::path tmp = st.root.string() + ".commit-" + st.tx->id();
  try {
    layout::write_root(tmp, cur);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  layout::crash_point("root-written");
  if (::rename(tmp.c_str(), st.root.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw LibraryError(ctx + ": cannot rename the new root into place: " + err);
  }
  st.committed = true;
  layout::sync_path(st.root.parent_path().empty() ? std::filesystem::path(".") : st.root.parent_path(), true);
  layout::crash_point("renamed");

  // 4. Reclaim what no reader can see; a failure here leaves garbage for the next commit, never a lost commit.
  try {
    reclaimed_ = layout::collect(st.root, st.data, cur, layout::transactions_in_flight(st.data, st.tx->id()) == 0);
  } catch (const std::exception&) {
  }
  layout::crash_point("collected");
}

}  // namespace specula::store
