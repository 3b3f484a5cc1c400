#pragma once
// Inside store/ only: chunk compression. HDF5's shuffle+deflate filters applied with libdeflate on every thread,
// the compressed chunks handed to H5Dwrite_chunk in order: the bytes HDF5's own filters would store, faster.
#include <omp.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"
#include "specula/store/detail/objects.h"

namespace specula::store {

/// Shuffles then deflates (zlib stream) `elems` floats into dst; returns the compressed size (0 on failure).
/// Thread-safe.
std::size_t shuffle_deflate(const float* plain, std::size_t elems, int level, std::vector<unsigned char>& dst);

/// The filter pipeline of a chunked dataset when it is HDF5's shuffle (first) and/or deflate (last) and nothing
/// else (known), which decode_chunk undoes.
struct ChunkFilters {
  bool known = false, shuffle = false, deflate = false;
  /// Whether a chunk stored with this filter mask (bit i set: filter i skipped) is deflated, shuffled.
  bool deflated(unsigned mask) const { return deflate && !(mask & (1u << (shuffle ? 1 : 0))); }
  bool shuffled(unsigned mask) const { return shuffle && !(mask & 1u); }
};
/// The filters of dataset creation properties dcpl (known false for a pipeline with other filters).
ChunkFilters chunk_filters(hid_t dcpl);

/// The floats of one stored chunk (size bytes at data) with HDF5's deflate and/or shuffle filters undone as
/// deflated and shuffled say: in a buffer of the calling thread (valid until its next call), or data itself with
/// neither; nullptr when it does not decode to exactly plain_bytes. Thread-safe.
const float* decode_chunk(const unsigned char* data, std::size_t size, bool deflated, bool shuffled,
                          std::size_t plain_bytes);

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
    parallel_for(
        n, [] { return std::vector<float>(); },
        [&](std::size_t j, std::vector<float>& plain) {
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

/// Writes rows [y0, y0 + h) of a shuffle+deflate cube chunk by chunk (write_chunks_deflated); y0 and h are whole
/// chunk rows (h may end at the cube's last row); the bytes are what HDF5's own filters would store. Pixels whose
/// mask byte is 0 (mask may be null) are stored as zeros.
void write_rows_deflated(hid_t ds, const float* data, const std::uint8_t* mask, std::size_t y0, std::size_t h,
                         std::size_t w, std::size_t b, std::size_t ch, std::size_t cw, int level,
                         const std::string& ctx);

}  // namespace specula::store
