#pragma once
// Streams the valid spectra of a selection of images (or one collection) in blocks: memory is bounded by
// the block size, never by the number of spectra. Blocks follow the chunk layout, so streaming every
// block in order reads every chunk once. read() may be called from several threads at once.
#include <omp.h>

#include <Eigen/Core>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "specula/core/colour.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/store/store.h"

namespace specula::store {

/// Which spectra to stream: images whose names match any glob (all images when empty), one collection, or the
/// values of one set of scattered BRDF samples.
struct Selection {
  std::vector<std::string> image_globs;
  std::string collection;
  std::string samples;
};

class BlockReader {
 public:
  /// Resolves the selection; throws InputError if nothing matches or the sources' wavelength grids differ.
  /// Blocks hold whole chunk rows, grouped until they reach about min_block_pixels pixels.
  BlockReader(const Store& store, const Selection& selection, std::size_t min_block_pixels = 32768);
  /// The same over several stores read as one database (in the given order): images matching the selection in
  /// each, or the collection of that name in each; throws InputError if one store has none or grids differ.
  BlockReader(const std::vector<Store>& stores, const Selection& selection, std::size_t min_block_pixels = 32768);
  BlockReader(const BlockReader&) = delete;
  BlockReader& operator=(const BlockReader&) = delete;
  ~BlockReader();
  /// True when every source is read by direct chunk access (no HDF5 lock on the data path).
  bool direct() const;

  std::size_t bands() const { return wavelengths_.size(); }
  const WavelengthGrid& wavelengths() const { return wavelengths_; }
  const std::string& units() const { return units_; }
  std::size_t block_count() const { return blocks_.size(); }
  /// Number of valid spectra over all blocks.
  std::uint64_t spectra() const { return spectra_; }
  /// Largest number of spectra a block can yield (size output buffers with it).
  std::size_t max_block_spectra() const { return max_block_; }
  /// Names of the selected images (or the collection); with several stores, prefixed by the store's file name and ':'.
  const std::vector<std::string>& source_names() const { return names_; }
  /// Index into source_names() of block i.
  std::size_t block_source(std::size_t i) const { return blocks_.at(i).source; }
  /// Where block i lies, for messages: "db.h5: image 'a' rows 0-31" (or "collection 'c' spectra ...").
  std::string describe_block(std::size_t i) const;
  /// First row (image row or spectrum index) of block i within its source.
  std::size_t block_first_row(std::size_t i) const { return blocks_.at(i).row0; }

  /// Block i as read from the file, before the mask is applied: caller-owned buffers reused across calls.
  struct RawBlock {
    std::vector<float> values;       // pixels x bands, band-fastest
    std::vector<std::uint8_t> mask;  // pixels entries (nonzero: valid); empty when every pixel is valid
    std::size_t pixels = 0, valid = 0;
    /// Spectrum p (valid or not) of the block.
    const float* spectrum(std::size_t p, std::size_t bands) const { return values.data() + p * bands; }
    /// True when pixel p holds a valid spectrum.
    bool is_valid(std::size_t p) const { return mask.empty() || mask[p] != 0; }
  };
  /// Reads block i without compacting it: consumers that skip invalid pixels themselves save a copy.
  void read_raw(std::size_t i, RawBlock& out) const;
  /// The valid spectra of `raw` in order into out (raw.valid x bands, band fastest; float or double); out may be
  /// raw.values.data() (compacted in place: nothing moves while the pixels before are all valid).
  template <class T>
  static void compact(const RawBlock& raw, std::size_t bands, T* out);
  /// Reads block i's valid spectra into out (resized to n x bands, one spectrum per row). Thread-safe.
  void read(std::size_t i, RowMatrixXf& out) const;
  /// As above, in double precision.
  void read(std::size_t i, RowMatrixXd& out) const;

 private:
  // Where each chunk of a source's spectra lies in the file, so blocks are read with pread and decoded
  // (inflate, unshuffle) on the calling thread instead of inside HDF5's global lock.
  struct ChunkRef {
    std::uint64_t address = 0, size = 0;  // size 0: never written, reads as zeros
    unsigned filter_mask = 0;             // bit i set: filter i was skipped for this chunk
  };
  struct SourceData {
    std::size_t store = 0;               // index into stores_
    std::shared_ptr<h5::Id> cube, mask;  // mask null for collections and samples
    std::string kind;                    // "image", "collection" or "samples"
    std::size_t width = 0;               // pixels per row (1 for collections)
    bool direct = false;                 // chunk map below is usable (filters: none, or shuffle then deflate)
    bool shuffle = false, deflate = false;
    std::size_t chunk_rows = 0, chunk_cols = 0, col_chunks = 0;
    std::vector<ChunkRef> chunks;  // row-chunk major
    int fd = -1;                   // the data file holding the chunks (a duplicate of HDF5's descriptor)
  };
  void add_store(std::size_t index, const Selection& selection, std::size_t min_block_pixels, bool prefix);
  void map_chunks(SourceData& sd, std::size_t rows) const;
  void pread_all(const SourceData& src, unsigned char* dst, std::size_t size, std::uint64_t address) const;
  void read_direct(const SourceData& src, std::size_t row0, std::size_t rows, float* out) const;
  struct Block {
    std::size_t source;
    std::size_t row0, rows;
  };
  template <class T>
  void read_block(std::size_t i, Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& out) const;

  std::vector<Store> stores_;
  WavelengthGrid wavelengths_;
  std::string units_;
  std::vector<std::string> names_;
  std::vector<SourceData> sources_;
  std::vector<Block> blocks_;
  std::uint64_t spectra_ = 0;
  std::size_t max_block_ = 0;
};

/// Streams every block through fn(block_index, spectra, thread) on all OpenMP threads, each thread with its
/// own buffer; checks for interruption between blocks. The first exception thrown by fn or a read stops the
/// stream and is rethrown here. Results that must not depend on the thread count should be stored per block
/// and merged in block order by the caller.
template <class T, class Fn>
void for_each_block(const BlockReader& reader, Fn&& fn) {
  using Matrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  parallel_for(
      reader.block_count(), [] { return Matrix(); },
      [&](std::size_t i, Matrix& buffer) {
        reader.read(i, buffer);
        fn(i, static_cast<const Matrix&>(buffer), omp_get_thread_num());
      });
}

}  // namespace specula::store
