// BRDF grids in the MERL layout: bands x 90 x 90 x 180 float32, chunked by theta_h rows of one band.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/core/text.h"
#include "specula/store/detail/deflate.h"
#include "specula/store/detail/grid_parameterisation.h"
#include "specula/store/detail/objects.h"
#include "specula/store/detail/writer_state.h"
#include "specula/store/grid_rows.h"

namespace specula::store {

GridInfo Store::grid_info(const std::string& name) const {
  const std::string path = "/grids/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no grid '" + name + "' (grids: " + join(grids()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
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
  info.parameterisation = read_parameterisation(g, ctx);
  return info;
}

Grid Store::read_grid(const std::string& name) const {
  GridInfo info = grid_info(name);
  const std::string ctx = label() + ": /grids/" + name;
  h5::Id g = open_group(StoreAccess::root(*this), "/grids/" + name, ctx);
  Grid grid;
  grid.wavelengths = info.wavelengths;
  grid.scale = info.scale;
  grid.units = info.units;
  grid.provenance = info.provenance;
  grid.parameterisation = std::move(info.parameterisation);
  grid.brdf.resize(info.bands * brdf::kMerlCells);
  h5::Id ds = open_dataset(g, "brdf", ctx);
  if (!grid.brdf.empty())
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, grid.brdf.data()), ctx, "cannot read brdf");
  return grid;
}

void read_grid_rows(const Store& s, const std::string& name, std::size_t theta_h0, std::size_t rows,
                    std::span<float> out) {
  const std::string ctx = s.label() + ": /grids/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(s), "/grids/" + name))
    throw InputError(s.label() + ": no grid '" + name + "' (grids: " + join(s.grids()) + ")");
  h5::Id g = open_group(StoreAccess::root(s), "/grids/" + name, ctx);
  h5::Id ds = open_dataset(g, "brdf", ctx);
  const auto dims = h5::shape(ds, ctx);
  if (dims.size() != 4 || dims[1] != kGridDims[0] || dims[2] != kGridDims[1] || dims[3] != kGridDims[2])
    throw InputError(ctx + "/brdf: expected shape (bands, 90, 90, 180), the MERL layout");
  const std::size_t row = std::size_t(kGridDims[1] * kGridDims[2]);
  if (theta_h0 + rows > kGridDims[0] || out.size() != dims[0] * rows * row)
    throw UsageError(ctx + ": theta_h rows [" + std::to_string(theta_h0) + ", " + std::to_string(theta_h0 + rows) +
                     ") of 90, or " + std::to_string(out.size()) + " values for them");
  if (rows == 0 || dims[0] == 0) return;
  const hsize_t start[4] = {0, theta_h0, 0, 0}, count[4] = {dims[0], rows, kGridDims[1], kGridDims[2]};
  read_hyperslab(ds, H5T_NATIVE_FLOAT, start, count, out.data(), ctx);
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
    if (grid.parameterisation) write_parameterisation(g, *grid.parameterisation, ctx);
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

}  // namespace specula::store
