#include <libdeflate.h>

#include <array>
#include <memory>

#include "specula/store/detail/deflate.h"

namespace specula::store {

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

namespace {

// Undoes HDF5's shuffle filter: byte k of element i was stored at k * n + i.
void unshuffle4(const unsigned char* in, std::size_t n, unsigned char* out) {
  const unsigned char* b0 = in;
  const unsigned char* b1 = in + n;
  const unsigned char* b2 = in + 2 * n;
  const unsigned char* b3 = in + 3 * n;
  for (std::size_t i = 0; i < n; ++i) {
    out[4 * i] = b0[i];
    out[4 * i + 1] = b1[i];
    out[4 * i + 2] = b2[i];
    out[4 * i + 3] = b3[i];
  }
}

}  // namespace

ChunkFilters chunk_filters(hid_t dcpl) {
  ChunkFilters c;
  const int nf = H5Pget_nfilters(dcpl);
  for (int i = 0; i < nf; ++i) {
    unsigned flags = 0, values[8];
    std::size_t nvalues = 8;
    const H5Z_filter_t f = H5Pget_filter2(dcpl, unsigned(i), &flags, &nvalues, values, 0, nullptr, nullptr);
    if (f == H5Z_FILTER_SHUFFLE && i == 0)
      c.shuffle = true;
    else if (f == H5Z_FILTER_DEFLATE && i == nf - 1)
      c.deflate = true;
    else
      return {};
  }
  c.known = true;
  return c;
}

const float* decode_chunk(const unsigned char* data, std::size_t size, bool deflated, bool shuffled,
                          std::size_t plain_bytes) {
  thread_local std::vector<unsigned char> plain, unshuffled;
  if (deflated) {
    thread_local std::unique_ptr<libdeflate_decompressor, void (*)(libdeflate_decompressor*)> inflater(
        libdeflate_alloc_decompressor(), libdeflate_free_decompressor);
    plain.resize(plain_bytes);
    std::size_t len = 0;
    if (!inflater ||
        libdeflate_zlib_decompress(inflater.get(), data, size, plain.data(), plain.size(), &len) !=
            LIBDEFLATE_SUCCESS ||
        len != plain_bytes)
      return nullptr;
    data = plain.data();
    size = len;
  } else if (size != plain_bytes) {
    return nullptr;
  }
  if (shuffled) {
    unshuffled.resize(size);
    unshuffle4(data, size / 4, unshuffled.data());
    data = unshuffled.data();
  }
  return reinterpret_cast<const float*>(data);
}

void write_rows_deflated(hid_t ds, const float* data, const std::uint8_t* mask, std::size_t y0, std::size_t h,
                         std::size_t w, std::size_t b, std::size_t ch, std::size_t cw, int level,
                         const std::string& ctx) {
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
      [&](std::size_t k) {
        return std::array<hsize_t, 3>{y0 + (k / col_chunks) * ch, (k % col_chunks) * cw, 0};
      });
}

}  // namespace specula::store
