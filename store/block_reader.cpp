#include "store/block_reader.h"

#include <fnmatch.h>

#include "core/error.h"

namespace specula::store {
namespace {

h5::Id open_with_cache(hid_t file, const std::string& path, std::size_t cache_bytes, std::string_view ctx) {
  h5::Id dapl(h5::check(H5Pcreate(H5P_DATASET_ACCESS), ctx, "H5Pcreate"));
  h5::check(H5Pset_chunk_cache(dapl, 1031, cache_bytes, 1.0), ctx, "H5Pset_chunk_cache");
  return h5::Id(h5::check(H5Dopen2(file, path.c_str(), dapl), ctx, "cannot open " + path));
}

bool matches(const std::vector<std::string>& globs, const std::string& name) {
  if (globs.empty()) return true;
  for (const auto& g : globs)
    if (::fnmatch(g.c_str(), name.c_str(), 0) == 0) return true;
  return false;
}

std::size_t group_rows(std::size_t chunk_rows, std::size_t width, std::size_t min_pixels) {
  const std::size_t per_chunk = std::max<std::size_t>(1, chunk_rows) * std::max<std::size_t>(1, width);
  const std::size_t chunks = std::max<std::size_t>(1, (min_pixels + per_chunk - 1) / per_chunk);
  return std::max<std::size_t>(1, chunk_rows) * chunks;
}

}  // namespace

BlockReader::BlockReader(const Store& store, const Selection& selection, std::size_t min_block_pixels)
    : store_(store) {
  const std::string ctx = store.label();
  if (!selection.collection.empty()) {
    if (!selection.image_globs.empty())
      throw UsageError("select either images or a collection, not both");
    const CollectionInfo info = store.collection_info(selection.collection);
    wavelengths_ = info.wavelengths;
    units_ = info.units;
    names_ = {info.name};
    const std::size_t rows_per_block = group_rows(info.chunk_rows ? info.chunk_rows : info.size, 1, min_block_pixels);
    SourceData sd;
    sd.cube = open_with_cache(store.file(), "/collections/" + info.name + "/spectra",
                              rows_per_block * info.bands * sizeof(float) * 2, ctx);
    sd.width = 1;
    sources_.push_back(std::move(sd));
    for (std::size_t r = 0; r < info.size; r += rows_per_block)
      blocks_.push_back({0, r, std::min(rows_per_block, info.size - r)});
    spectra_ = info.size;
    max_block_ = std::min(rows_per_block, info.size);
    return;
  }
  for (const auto& name : store.images()) {
    if (!matches(selection.image_globs, name)) continue;
    const ImageInfo info = store.image_info(name);
    if (names_.empty()) {
      wavelengths_ = info.wavelengths;
      units_ = info.units;
    } else if (!info.wavelengths.approx_equal(wavelengths_)) {
      throw InputError(ctx + ": image '" + name + "' has " + info.wavelengths.describe() + ", image '" + names_.front() +
                       "' has " + wavelengths_.describe() + "; select images on one grid with --images");
    }
    const std::size_t rows_per_block = group_rows(info.chunk_rows, info.width, min_block_pixels);
    const std::size_t cache = rows_per_block * info.width * info.bands * sizeof(float) * 2;
    SourceData sd;
    sd.cube = open_with_cache(store.file(), "/images/" + name + "/cube", cache, ctx);
    sd.mask = open_with_cache(store.file(), "/images/" + name + "/mask", cache / info.bands + 4096, ctx);
    sd.width = info.width;
    const std::size_t source = names_.size();
    names_.push_back(name);
    sources_.push_back(std::move(sd));
    for (std::size_t r = 0; r < info.height; r += rows_per_block) {
      const std::size_t rows = std::min(rows_per_block, info.height - r);
      blocks_.push_back({source, r, rows});
      max_block_ = std::max(max_block_, rows * info.width);
    }
    spectra_ += info.valid_pixels;
  }
  if (names_.empty()) {
    std::string globs;
    for (const auto& g : selection.image_globs) globs += (globs.empty() ? "" : " ") + g;
    throw InputError(ctx + ": no image matches '" + globs + "' (" + std::to_string(store.images().size()) +
                     " images in the store; `specula ls " + store.path().string() + "` lists them)");
  }
}

template <class T>
void BlockReader::read_block(std::size_t i, Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& out) const {
  const Block& blk = blocks_.at(i);
  const SourceData& src = sources_[blk.source];
  const std::string ctx = store_.label() + ": " + names_[blk.source];
  const std::size_t b = bands();
  const std::size_t px = blk.rows * src.width;
  const bool image = src.mask.valid();

  thread_local std::vector<float> raw;
  thread_local std::vector<std::uint8_t> mask;
  raw.resize(px * b);
  const hsize_t start[3] = {blk.row0, 0, 0};
  const hsize_t count3[3] = {blk.rows, src.width, b};
  const hsize_t count2[2] = {blk.rows, b};
  const int rank = image ? 3 : 2;
  const hsize_t* count = image ? count3 : count2;
  {
    h5::Id fspace(h5::check(H5Dget_space(src.cube), ctx, "H5Dget_space"));
    h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr), ctx, "H5Sselect_hyperslab");
    h5::Id mspace(h5::check(H5Screate_simple(rank, count, nullptr), ctx, "H5Screate_simple"));
    h5::check(H5Dread(src.cube, H5T_NATIVE_FLOAT, mspace, fspace, H5P_DEFAULT, raw.data()), ctx, "cannot read spectra");
  }
  std::size_t valid = px;
  if (image) {
    mask.resize(px);
    h5::Id fspace(h5::check(H5Dget_space(src.mask), ctx, "H5Dget_space"));
    h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count3, nullptr), ctx, "H5Sselect_hyperslab");
    h5::Id mspace(h5::check(H5Screate_simple(2, count3, nullptr), ctx, "H5Screate_simple"));
    h5::check(H5Dread(src.mask, H5T_NATIVE_UINT8, mspace, fspace, H5P_DEFAULT, mask.data()), ctx, "cannot read mask");
    valid = 0;
    for (std::size_t p = 0; p < px; ++p) valid += mask[p] != 0;
  }
  out.resize(Eigen::Index(valid), Eigen::Index(b));
  if (valid == px) {
    out = Eigen::Map<const RowMatrixXf>(raw.data(), Eigen::Index(px), Eigen::Index(b)).template cast<T>();
    return;
  }
  Eigen::Index r = 0;
  for (std::size_t p = 0; p < px; ++p) {
    if (!mask[p]) continue;
    out.row(r++) = Eigen::Map<const Eigen::Matrix<float, 1, Eigen::Dynamic>>(raw.data() + p * b, Eigen::Index(b)).template cast<T>();
  }
}

void BlockReader::read(std::size_t i, RowMatrixXf& out) const { read_block(i, out); }
void BlockReader::read(std::size_t i, RowMatrixXd& out) const { read_block(i, out); }

}  // namespace specula::store
