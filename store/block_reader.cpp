#include "specula/store/block_reader.h"

#include <fcntl.h>
#include <fnmatch.h>
#include <unistd.h>

#include <cstring>
#include <memory>
#include <type_traits>

#include "specula/core/error.h"
#include "specula/store/detail/deflate.h"
#include "specula/store/detail/objects.h"
#include "specula/store/object_spec.h"

namespace specula::store {
namespace {

std::shared_ptr<h5::Id> open_with_cache(hid_t file, const std::string& path, std::size_t cache_bytes,
                                        std::string_view ctx) {
  h5::Id dapl(h5::check(H5Pcreate(H5P_DATASET_ACCESS), ctx, "H5Pcreate"));
  h5::check(H5Pset_chunk_cache(dapl, 1031, cache_bytes, 1.0), ctx, "H5Pset_chunk_cache");
  return std::make_shared<h5::Id>(h5::check(H5Dopen2(file, path.c_str(), dapl), ctx, "cannot open " + path));
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

BlockReader::~BlockReader() {
  for (const auto& s : sources_)
    if (s.fd >= 0) ::close(s.fd);
}

bool BlockReader::direct() const {
  for (const auto& s : sources_)
    if (!s.direct) return false;
  return !sources_.empty();
}

void BlockReader::map_chunks(SourceData& sd, std::size_t rows) const {
  const std::string ctx = stores_[sd.store].label();
  h5::Id dcpl(h5::check(H5Dget_create_plist(*sd.cube), ctx, "H5Dget_create_plist"));
  if (H5Pget_layout(dcpl) != H5D_CHUNKED) return;
  const ChunkFilters filters = chunk_filters(dcpl);
  if (!filters.known) return;  // an unknown pipeline: HDF5 decodes it
  sd.shuffle = filters.shuffle;
  sd.deflate = filters.deflate;
  hsize_t cdims[3] = {0, 0, 0};
  const int rank = H5Pget_chunk(dcpl, 3, cdims);
  if (rank < 2 || cdims[rank - 1] != bands()) return;
  sd.chunk_rows = cdims[0];
  sd.chunk_cols = rank == 3 ? cdims[1] : 1;
  sd.col_chunks = (sd.width + sd.chunk_cols - 1) / sd.chunk_cols;
  const std::size_t row_chunks = (rows + sd.chunk_rows - 1) / sd.chunk_rows;
  sd.chunks.resize(row_chunks * sd.col_chunks);
  for (std::size_t r = 0; r < row_chunks; ++r)
    for (std::size_t c = 0; c < sd.col_chunks; ++c) {
      hsize_t offset[3] = {r * sd.chunk_rows, c * sd.chunk_cols, 0};
      unsigned fmask = 0;
      haddr_t addr = 0;
      hsize_t size = 0;
      if (H5Dget_chunk_info_by_coord(*sd.cube, offset, &fmask, &addr, &size) < 0) {
        H5Eclear2(H5E_DEFAULT);
        sd.chunks.clear();
        return;
      }
      auto& ref = sd.chunks[r * sd.col_chunks + c];
      ref.address = addr == HADDR_UNDEF ? 0 : addr;
      ref.size = addr == HADDR_UNDEF ? 0 : size;
      ref.filter_mask = fmask;
    }
  // The dataset may live in a data file of its own (format 2): read the file HDF5 opened for it.
  h5::Id file(h5::check(H5Iget_file_id(*sd.cube), ctx, "H5Iget_file_id"));
  void* handle = nullptr;
  if (H5Fget_vfd_handle(file, H5P_DEFAULT, &handle) < 0 || !handle) {
    H5Eclear2(H5E_DEFAULT);
    sd.chunks.clear();
    return;
  }
  sd.fd = ::fcntl(*static_cast<int*>(handle), F_DUPFD_CLOEXEC, 0);
  if (sd.fd < 0) throw LibraryError(ctx + ": cannot duplicate a file descriptor: " + std::strerror(errno));
  sd.direct = true;
}

void BlockReader::pread_all(const SourceData& src, unsigned char* dst, std::size_t size, std::uint64_t address) const {
  std::size_t got = 0;
  while (got < size) {
    const ssize_t n = ::pread(src.fd, dst + got, size - got, off_t(address + got));
    if (n <= 0)
      throw LibraryError(stores_[src.store].label() + ": cannot read chunk at byte " + std::to_string(address) +
                         (n < 0 ? std::string(": ") + std::strerror(errno) : std::string(": file is truncated")));
    got += std::size_t(n);
  }
}

void BlockReader::read_direct(const SourceData& src, std::size_t row0, std::size_t rows, float* out) const {
  const std::size_t b = bands();
  const std::size_t chunk_values = src.chunk_rows * src.chunk_cols * b;
  thread_local std::vector<unsigned char> packed, plain;
  for (std::size_t r = row0 / src.chunk_rows; r * src.chunk_rows < row0 + rows; ++r) {
    const std::size_t y0 = r * src.chunk_rows;
    const std::size_t ny = std::min(src.chunk_rows, row0 + rows - y0);
    for (std::size_t c = 0; c < src.col_chunks; ++c) {
      const ChunkRef& ref = src.chunks[r * src.col_chunks + c];
      const std::size_t x0 = c * src.chunk_cols;
      const std::size_t nx = std::min(src.chunk_cols, src.width - x0);
      if (ref.size == chunk_values * sizeof(float) && !src.deflate && !src.shuffle && src.chunk_cols == src.width) {
        // Plain whole-row chunk: its first ny rows go straight into the block, without a staging copy.
        pread_all(src, reinterpret_cast<unsigned char*>(out + (y0 - row0) * src.width * b),
                  ny * src.width * b * sizeof(float), ref.address);
        continue;
      }
      const float* values = nullptr;
      plain.resize(chunk_values * sizeof(float));
      if (ref.size == 0) {
        std::memset(plain.data(), 0, plain.size());
        values = reinterpret_cast<const float*>(plain.data());
      } else {
        packed.resize(ref.size);
        pread_all(src, packed.data(), ref.size, ref.address);
        const ChunkFilters filters{.known = true, .shuffle = src.shuffle, .deflate = src.deflate};
        values = decode_chunk(packed.data(), ref.size, filters.deflated(ref.filter_mask),
                              filters.shuffled(ref.filter_mask), plain.size());
        if (!values)
          throw InputError(stores_[src.store].label() + ": corrupt chunk at byte " + std::to_string(ref.address) +
                           " (" + std::to_string(ref.size) + " bytes that do not decode to " +
                           std::to_string(plain.size()) + ")");
      }
      // Chunk rows [y0, y0 + ny) x columns [x0, x0 + nx) into the block buffer.
      for (std::size_t y = 0; y < ny; ++y)
        std::memcpy(out + ((y0 + y - row0) * src.width + x0) * b, values + y * src.chunk_cols * b,
                    nx * b * sizeof(float));
    }
  }
}

BlockReader::BlockReader(const Store& store, const Selection& selection, std::size_t min_block_pixels)
    : BlockReader(std::vector<Store>{store}, selection, min_block_pixels) {}

BlockReader::BlockReader(const std::vector<Store>& stores, const Selection& selection, std::size_t min_block_pixels)
    : stores_(stores) {
  if (stores_.empty()) throw UsageError("a block reader needs at least one store");
  if (int(!selection.collection.empty()) + int(!selection.image_globs.empty()) + int(!selection.samples.empty()) > 1)
    throw UsageError("select images, a collection or samples, only one of them");
  try {
    for (std::size_t i = 0; i < stores_.size(); ++i) add_store(i, selection, min_block_pixels, stores_.size() > 1);
  } catch (...) {
    for (const auto& s : sources_)
      if (s.fd >= 0) ::close(s.fd);
    throw;
  }
}

void BlockReader::add_store(std::size_t index, const Selection& selection, std::size_t min_block_pixels, bool prefix) {
  const Store& store = stores_[index];
  const std::string ctx = store.label();
  const std::string tag = prefix ? ctx + ":" : "";
  // The first source fixes the grid; every later one must match it.
  auto check_grid = [&](const WavelengthGrid& grid, const std::string& what) {
    if (names_.empty()) return;
    if (!grid.approx_equal(wavelengths_))
      throw InputError(ctx + ": " + what + " has " + grid.describe() + ", '" + names_.front() + "' has " +
                       wavelengths_.describe() + "; analyse sources on one wavelength grid together");
  };
  if (!selection.collection.empty() || !selection.samples.empty()) {
    const bool samples = !selection.samples.empty();
    CollectionInfo info;
    if (samples) {
      const SamplesInfo si = store.samples_info(selection.samples);
      info.name = si.name;
      info.size = si.size;
      info.bands = si.bands;
      info.wavelengths = si.wavelengths;
      info.units = si.units;
      info.chunk_rows = si.chunk_rows;
    } else {
      info = store.collection_info(selection.collection);
    }
    check_grid(info.wavelengths, (samples ? "samples '" : "collection '") + info.name + "'");
    if (names_.empty()) {
      wavelengths_ = info.wavelengths;
      units_ = info.units;
    }
    const std::size_t rows_per_block = group_rows(info.chunk_rows ? info.chunk_rows : info.size, 1, min_block_pixels);
    SourceData sd;
    sd.store = index;
    sd.kind = samples ? "samples" : "collection";
    sd.cube =
        open_with_cache(StoreAccess::root(store),
                        (samples ? "/samples/" : "/collections/") + info.name + (samples ? "/values" : "/spectra"),
                        rows_per_block * info.bands * sizeof(float) * 2, ctx);
    sd.width = 1;
    map_chunks(sd, info.size);
    const std::size_t source = names_.size();
    names_.push_back(tag + info.name);
    sources_.push_back(std::move(sd));
    for (std::size_t r = 0; r < info.size; r += rows_per_block)
      blocks_.push_back({source, r, std::min(rows_per_block, info.size - r)});
    spectra_ += info.size;
    max_block_ = std::max(max_block_, std::min(rows_per_block, info.size));
    return;
  }
  const std::size_t before = names_.size();
  for (const auto& name : store.images()) {
    if (!matches(selection.image_globs, name)) continue;
    const ImageInfo info = store.image_info(name);
    check_grid(info.wavelengths, "image '" + name + "'");
    if (names_.empty()) {
      wavelengths_ = info.wavelengths;
      units_ = info.units;
    }
    const std::size_t rows_per_block = group_rows(info.chunk_rows, info.width, min_block_pixels);
    const std::size_t cache = rows_per_block * info.width * info.bands * sizeof(float) * 2;
    SourceData sd;
    sd.store = index;
    sd.kind = "image";
    sd.cube = open_with_cache(StoreAccess::root(store), "/images/" + name + "/cube", cache, ctx);
    sd.mask = open_with_cache(StoreAccess::root(store), "/images/" + name + "/mask", cache / info.bands + 4096, ctx);
    sd.width = info.width;
    map_chunks(sd, info.height);
    const std::size_t source = names_.size();
    names_.push_back(tag + name);
    sources_.push_back(std::move(sd));
    for (std::size_t r = 0; r < info.height; r += rows_per_block) {
      const std::size_t rows = std::min(rows_per_block, info.height - r);
      blocks_.push_back({source, r, rows});
      max_block_ = std::max(max_block_, rows * info.width);
    }
    spectra_ += info.valid_pixels;
  }
  if (names_.size() == before) {
    std::string globs;
    for (const auto& g : selection.image_globs) globs += (globs.empty() ? "" : " ") + g;
    throw InputError(ctx + ": no image matches '" + (globs.empty() ? std::string("*") : globs) + "' (" +
                     std::to_string(store.images().size()) + " images in the store; `specula ls " +
                     store.path().string() + "` lists them)");
  }
}

std::string BlockReader::describe_block(std::size_t i) const {
  const Block& blk = blocks_.at(i);
  const SourceData& src = sources_[blk.source];
  std::string name = names_[blk.source];
  if (const auto spec = parse_object_spec(name); stores_.size() > 1 && spec) name = spec->name;
  return stores_[src.store].label() + ": " + src.kind + " '" + name + "' " +
         ((src.mask != nullptr) ? "rows " : "spectra ") + std::to_string(blk.row0) + "-" +
         std::to_string(blk.row0 + blk.rows - 1);
}

void BlockReader::read_raw(std::size_t i, RawBlock& out) const {
  const Block& blk = blocks_.at(i);
  const SourceData& src = sources_[blk.source];
  const std::string ctx = stores_[src.store].label() + ": " + names_[blk.source];
  const std::size_t b = bands();
  const std::size_t px = blk.rows * src.width;
  const bool image = (src.mask != nullptr);
  out.pixels = px;
  out.values.resize(px * b);
  const hsize_t start[3] = {blk.row0, 0, 0};
  const hsize_t count3[3] = {blk.rows, src.width, b};
  const hsize_t count2[2] = {blk.rows, b};
  if (src.direct) {
    read_direct(src, blk.row0, blk.rows, out.values.data());
  } else {
    const int rank = image ? 3 : 2;
    const hsize_t* count = image ? count3 : count2;
    h5::Id fspace(h5::check(H5Dget_space(*src.cube), ctx, "H5Dget_space"));
    h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr), ctx, "H5Sselect_hyperslab");
    h5::Id mspace(h5::check(H5Screate_simple(rank, count, nullptr), ctx, "H5Screate_simple"));
    h5::check(H5Dread(*src.cube, H5T_NATIVE_FLOAT, mspace, fspace, H5P_DEFAULT, out.values.data()), ctx,
              "cannot read spectra");
  }
  out.valid = px;
  out.mask.clear();
  if (!image) return;
  out.mask.resize(px);
  h5::Id fspace(h5::check(H5Dget_space(*src.mask), ctx, "H5Dget_space"));
  h5::check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count3, nullptr), ctx, "H5Sselect_hyperslab");
  h5::Id mspace(h5::check(H5Screate_simple(2, count3, nullptr), ctx, "H5Screate_simple"));
  h5::check(H5Dread(*src.mask, H5T_NATIVE_UINT8, mspace, fspace, H5P_DEFAULT, out.mask.data()), ctx,
            "cannot read mask");
  std::size_t valid = 0;
  for (std::size_t p = 0; p < px; ++p) valid += out.mask[p] != 0;
  out.valid = valid;
  if (valid == px) out.mask.clear();
}

template <class T>
void BlockReader::read_block(std::size_t i,
                             Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& out) const {
  thread_local RawBlock raw;
  read_raw(i, raw);
  out.resize(Eigen::Index(raw.valid), Eigen::Index(bands()));
  compact(raw, bands(), out.data());
}

template <class T>
void BlockReader::compact(const RawBlock& raw, std::size_t bands, T* out) {
  T* dst = out;
  // Copies runs of consecutive valid pixels at once.
  for (std::size_t p = 0; p < raw.pixels;) {
    if (!raw.is_valid(p)) {
      ++p;
      continue;
    }
    std::size_t q = p + 1;
    while (q < raw.pixels && raw.is_valid(q)) ++q;
    const float* src = raw.spectrum(p, bands);
    const std::size_t len = (q - p) * bands;
    if constexpr (std::is_same_v<T, float>) {
      if (static_cast<const float*>(dst) != src) std::memmove(dst, src, len * sizeof(float));  // in place: dst <= src
    } else {
      std::copy(src, src + len, dst);
    }
    dst += len;
    p = q;
  }
}
template void BlockReader::compact<float>(const RawBlock&, std::size_t, float*);
template void BlockReader::compact<double>(const RawBlock&, std::size_t, double*);

void BlockReader::read(std::size_t i, RowMatrixXf& out) const { read_block(i, out); }
void BlockReader::read(std::size_t i, RowMatrixXd& out) const { read_block(i, out); }

}  // namespace specula::store
