// Coefficient maps: an image's pixels on a basis, stored with a copy of that basis.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"

namespace specula::store {

CoefficientsInfo Store::coefficients_info(const std::string& name) const {
  const std::string path = "/coefficients/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no coefficient map '" + name + "' (coefficient maps: " + join(coefficients()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
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
  if (dims.size() != 3 || dims[2] == 0)
    throw InputError(ctx + "/coefficients: expected 3 dimensions (height, width, k)");
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
  h5::Id g = open_group(StoreAccess::root(*this), "/coefficients/" + name, ctx);
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
  h5::Id g = open_group(StoreAccess::root(*this), "/coefficients/" + name, ctx);
  h5::Id ds = open_dataset(g, "coefficients", ctx);
  const hsize_t start[3] = {y0, 0, 0}, count[3] = {rows, info.width, info.k};
  read_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, coefficients.data(), ctx);
  if (mask.empty()) return;
  h5::Id mds = open_dataset(g, "mask", ctx);
  read_hyperslab(mds, H5T_NATIVE_UINT8, std::span<const hsize_t>(start, 2), std::span<const hsize_t>(count, 2),
                 mask.data(), ctx);
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
  if (basis.method == "pca") h5::write_vector(g, "mean", std::span<const double>(basis.mean.data(), b), ctx);

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
  h5::Id g = open_group(
      object_file("coefficients", name, "create the map with create_coefficients before writing rows"), path, ctx);
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

}  // namespace specula::store
