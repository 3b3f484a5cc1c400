// Images: metadata, whole and single-pixel reads, and writes whole (add_image) or by row strips (create_image).
#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/store/detail/deflate.h"
#include "specula/store/detail/objects.h"
#include "specula/store/detail/writer_state.h"

namespace specula::store {

ImageInfo Store::image_info(const std::string& name) const {
  const std::string path = "/images/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no image '" + name + "' (images: " + join(images()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
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

Cube Store::read_image(const std::string& name) const {
  const ImageInfo info = image_info(name);
  const std::string ctx = label() + ": /images/" + name;
  h5::Id g = open_group(StoreAccess::root(*this), "/images/" + name, ctx);
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
    throw UsageError(ctx + ": a pixel has " + std::to_string(info.bands) + " bands, the buffer " +
                     std::to_string(out.size()));
  h5::Id g = open_group(StoreAccess::root(*this), "/images/" + name, ctx);
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
  if (cube.data.size() != cube.height * cube.width * cube.bands ||
      (!cube.mask.empty() && cube.mask.size() != cube.height * cube.width))
    throw UsageError(ctx + ": cube buffers do not match its dimensions");
  if (cube.wavelengths.size() != cube.bands)
    throw InputError(src + ": image has " + std::to_string(cube.bands) + " bands but " +
                     std::to_string(cube.wavelengths.size()) + " wavelengths");
  if (!cube.fwhm.empty() && cube.fwhm.size() != cube.bands)
    throw InputError(src + ": " + std::to_string(cube.fwhm.size()) + " FWHM values for " + std::to_string(cube.bands) +
                     " bands");
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
  d.cube = h5::Id(h5::check(H5Dcreate2(g, "cube", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                            "cannot create cube"));
  h5::write_attr(d.cube, "axes", std::string_view("height,width,band"), ctx);
  h5::Id mspace(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id mdcpl = chunked_dcpl(std::span<const hsize_t>(chunk, 2), options_.compression, ctx);
  d.mask = h5::Id(h5::check(H5Dcreate2(g, "mask", H5T_STD_U8LE, mspace, H5P_DEFAULT, mdcpl, H5P_DEFAULT), ctx,
                            "cannot create mask"));
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
    write_rows_deflated(ds, cube.data.data(), cube.mask.empty() ? nullptr : cube.mask.data(), 0, cube.height,
                        cube.width, cube.bands, ch, cw, options_.compression.level, ctx);
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

std::size_t StoreWriter::create_image(const std::string& name, std::size_t height, std::size_t width,
                                      const WavelengthGrid& wavelengths, std::span<const double> fwhm,
                                      const std::string& units, const Provenance& provenance) {
  const std::string ctx = label() + ": /images/" + name;
  const std::string src = provenance.source_file.empty() ? name : provenance.source_file;
  if (height == 0 || width == 0 || wavelengths.empty())
    throw InputError(src + ": image is empty (" + std::to_string(height) + "x" + std::to_string(width) + "x" +
                     std::to_string(wavelengths.size()) + ")");
  if (!fwhm.empty() && fwhm.size() != wavelengths.size())
    throw InputError(src + ": " + std::to_string(fwhm.size()) + " FWHM values for " +
                     std::to_string(wavelengths.size()) + " bands");
  const hid_t f = begin("images", name, "image");
  std::size_t chunk_rows = 0;
  try {
    chunk_rows =
        create_image_datasets(f, name, height, width, wavelengths, fwhm, units, provenance, options_, ctx).chunk_rows;
  } catch (...) {
    state_->drop("images", name);
    throw;
  }
  WriterState::Pending& p = *state_->find("images", name);
  p.rows_expected = height;
  p.row_done.assign(height, false);
  return chunk_rows;
}

void StoreWriter::write_image_rows(const std::string& name, std::size_t y0, std::size_t rows,
                                   std::span<const float> spectra, std::span<const std::uint8_t> mask) {
  const std::string path = "/images/" + name, ctx = label() + ": " + path;
  h5::Id g =
      open_group(object_file("images", name, "create the image with create_image before writing rows"), path, ctx);
  WriterState::Pending& p = *state_->find("images", name);
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
                         std::to_string(q % width) + ", band " + std::to_string(b) +
                         "; mask such pixels before storing");
  }
  for (std::size_t y = y0; y < y0 + rows; ++y)
    if (p.row_done[y]) throw UsageError(ctx + ": row " + std::to_string(y) + " is written twice");
  const hsize_t start[3] = {y0, 0, 0}, cnt[3] = {rows, width, bands};
  const auto [ch, cw] = image_chunk(dims[0], width, bands);
  if (options_.compression.kind == Compression::Kind::deflate && y0 % ch == 0 &&
      (rows % ch == 0 || y0 + rows == dims[0]))
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

}  // namespace specula::store
