// Scattered BRDF samples: an extendible set of (angles, values) rows.
#include <algorithm>
#include <cmath>
#include <string>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"

namespace specula::store {
namespace {

// 1: angles, values, wavelengths; 2: also variance (one per value). Written only with a variance, so samples without
// one are laid out exactly as version 1.
constexpr long long kSamplesVersion = 2;

}  // namespace

SamplesInfo Store::samples_info(const std::string& name) const {
  const std::string path = "/samples/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no samples '" + name + "' (samples: " + join(samples()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
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
  const long long version = h5::has_attr(g, "samples_version") ? h5::read_int_attr(g, "samples_version", ctx) : 1;
  if (version > kSamplesVersion)
    throw InputError(ctx + ": samples version " + std::to_string(version) + " is newer than this specula reads (" +
                     std::to_string(kSamplesVersion) + "); upgrade specula");
  info.variance = h5::exists(g, "variance");
  if (info.variance && h5::shape(open_dataset(g, "variance", ctx), ctx) != dims)
    throw InputError(ctx + ": variance must have the shape of values");
  info.provenance = read_provenance(g, ctx);
  return info;
}

void Store::read_samples(const std::string& name, std::size_t first, std::size_t count, std::span<double> angles,
                         std::span<float> values, std::span<float> variance) const {
  const SamplesInfo info = samples_info(name);
  const std::string ctx = label() + ": /samples/" + name;
  const bool want_angles = !angles.empty(), want_values = !values.empty(), want_variance = !variance.empty();
  if (first > info.size || count > info.size - first || (want_angles && angles.size() != count * 4) ||
      (want_values && values.size() != count * info.bands) || (want_variance && variance.size() != count * info.bands))
    throw UsageError(ctx + ": read_samples range or buffer sizes are wrong");
  if (want_variance && !info.variance) throw UsageError(ctx + ": these samples carry no variance");
  if (count == 0) return;
  h5::Id g = open_group(StoreAccess::root(*this), "/samples/" + name, ctx);
  const hsize_t s2[2] = {first, 0}, ca[2] = {count, 4}, cv[2] = {count, info.bands};
  if (want_angles) read_hyperslab(open_dataset(g, "angles", ctx), H5T_NATIVE_DOUBLE, s2, ca, angles.data(), ctx);
  if (want_values) read_hyperslab(open_dataset(g, "values", ctx), H5T_NATIVE_FLOAT, s2, cv, values.data(), ctx);
  if (want_variance) read_hyperslab(open_dataset(g, "variance", ctx), H5T_NATIVE_FLOAT, s2, cv, variance.data(), ctx);
}

void StoreWriter::create_samples(const std::string& name, const WavelengthGrid& wavelengths, const std::string& units,
                                 const Provenance& provenance, bool variance) {
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
  h5::Id a(h5::check(H5Dcreate2(g, "angles", H5T_IEEE_F64LE, aspace, H5P_DEFAULT, adcpl, H5P_DEFAULT), ctx,
                     "cannot create angles"));
  h5::write_attr(a, "columns", std::string_view("theta_i,phi_i,theta_o,phi_o"), ctx);
  h5::write_attr(a, "units", std::string_view("rad"), ctx);
  h5::Id v(h5::check(H5Dcreate2(g, "values", H5T_IEEE_F32LE, vspace, H5P_DEFAULT, vdcpl, H5P_DEFAULT), ctx,
                     "cannot create values"));
  if (!variance) return;
  h5::write_attr(g, "samples_version", kSamplesVersion, ctx);
  h5::Id var(h5::check(H5Dcreate2(g, "variance", H5T_IEEE_F32LE, vspace, H5P_DEFAULT, vdcpl, H5P_DEFAULT), ctx,
                       "cannot create variance"));
  h5::write_attr(var, "units", std::string_view("(" + units + ")^2"), ctx);
}

void StoreWriter::append_samples(const std::string& name, std::span<const double> angles, std::span<const float> values,
                                 std::span<const float> variance) {
  const std::string ctx = label() + ": /samples/" + name;
  h5::Id g = open_group(object_file("samples", name, "create_samples first"), "/samples/" + name, ctx);
  h5::Id a = open_dataset(g, "angles", ctx);
  h5::Id v = open_dataset(g, "values", ctx);
  const auto vd = h5::shape(v, ctx);
  const hsize_t b = vd[1];
  if (angles.size() % 4 != 0 || values.size() != angles.size() / 4 * b)
    throw UsageError(ctx + ": append_samples needs n x 4 angles and n x " + std::to_string(b) + " values");
  const bool has_variance = h5::exists(g, "variance");
  if (has_variance ? variance.size() != values.size() : !variance.empty())
    throw UsageError(ctx + (has_variance ? ": append_samples needs a variance per value"
                                         : ": these samples were created without a variance"));
  const hsize_t n = angles.size() / 4;
  for (std::size_t i = 0; i < angles.size(); ++i)
    if (!std::isfinite(angles[i]))
      throw InputError(ctx + ": non-finite angle in sample " + std::to_string(vd[0] + i / 4));
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      throw InputError(ctx + ": non-finite value in sample " + std::to_string(vd[0] + i / b));
  for (std::size_t i = 0; i < variance.size(); ++i)
    if (!std::isfinite(variance[i]) || variance[i] < 0)
      throw InputError(ctx + ": negative or non-finite variance in sample " + std::to_string(vd[0] + i / b));
  if (n == 0) return;
  const hsize_t new_a[2] = {vd[0] + n, 4}, new_v[2] = {vd[0] + n, b};
  h5::check(H5Dset_extent(a, new_a), ctx, "cannot extend angles");
  h5::check(H5Dset_extent(v, new_v), ctx, "cannot extend values");
  const hsize_t start[2] = {vd[0], 0}, ca[2] = {n, 4}, cv[2] = {n, b};
  write_hyperslab(a, H5T_NATIVE_DOUBLE, start, ca, angles.data(), ctx);
  write_hyperslab(v, H5T_NATIVE_FLOAT, start, cv, values.data(), ctx);
  if (!has_variance) return;
  h5::Id var = open_dataset(g, "variance", ctx);
  h5::check(H5Dset_extent(var, new_v), ctx, "cannot extend variance");
  write_hyperslab(var, H5T_NATIVE_FLOAT, start, cv, variance.data(), ctx);
}

}  // namespace specula::store
