// Collections: named spectra on one wavelength grid.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/store/detail/objects.h"

namespace specula::store {

CollectionInfo Store::collection_info(const std::string& name) const {
  const std::string path = "/collections/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no collection '" + name + "' (collections: " + join(collections()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
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

Collection Store::read_collection(const std::string& name) const {
  const CollectionInfo info = collection_info(name);
  const std::string ctx = label() + ": /collections/" + name;
  h5::Id g = open_group(StoreAccess::root(*this), "/collections/" + name, ctx);
  Collection c;
  c.wavelengths = info.wavelengths;
  c.units = info.units;
  c.provenance = info.provenance;
  c.values.resize(info.size * info.bands);
  h5::Id ds = open_dataset(g, "spectra", ctx);
  if (!c.values.empty())
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, c.values.data()), ctx,
              "cannot read spectra");
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
  h5::Id ds(h5::check(H5Dcreate2(g, "spectra", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                      "cannot create spectra"));
  for (hsize_t r0 = 0; r0 < n; r0 += chunk[0]) {
    check_interrupt();
    const hsize_t start[2] = {r0, 0}, count[2] = {std::min<hsize_t>(chunk[0], n - r0), b};
    write_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, col.values.data() + r0 * b, ctx);
  }
  const hsize_t ndims[1] = {n};
  h5::Id nspace(h5::check(H5Screate_simple(1, ndims, nullptr), ctx, "H5Screate_simple"));
  h5::Id type = vlen_string_type(ctx);
  h5::Id nds(h5::check(H5Dcreate2(g, "names", type, nspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
                       "cannot create names"));
  std::vector<const char*> ptrs;
  for (const auto& s : col.names) ptrs.push_back(s.c_str());
  h5::check(H5Dwrite(nds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()), ctx, "cannot write names");
}

}  // namespace specula::store
