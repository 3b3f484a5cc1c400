#include "specula/acquire/store_samples.h"

#include <algorithm>

#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::acquire {

StoreSamples::StoreSamples(const store::Store& store, std::string name)
    : store_(std::make_unique<store::Store>(store)), name_(std::move(name)) {
  const store::SamplesInfo info = store_->samples_info(name_);
  size_ = info.size;
  bands_ = info.bands;
  variance_ = info.variance;
  // One reader block per storage chunk (a contiguous dataset is read through HDF5 in blocks of 2^16 rows).
  reader_rows_ = info.chunk_rows ? info.chunk_rows : std::size_t(1) << 16;
  if (info.chunk_rows)
    reader_ = std::make_unique<store::BlockReader>(*store_, store::Selection{.samples = name_}, info.chunk_rows);
  block_rows_ = std::max<std::size_t>(1, (std::size_t(32) << 20) / (4 * bands_ * reader_rows_)) * reader_rows_;
}

StoreSamples::~StoreSamples() = default;

void StoreSamples::read_angles(std::size_t first, std::size_t count, std::span<double> out) const {
  store_->read_samples(name_, first, count, out, {});
}

void StoreSamples::read_variance(std::size_t first, std::size_t count, std::span<float> out) const {
  store_->read_samples(name_, first, count, {}, {}, out);
}

void StoreSamples::read_values(std::size_t first, std::size_t count, std::span<float> out) const {
  if (first > size_ || count > size_ - first || out.size() != count * bands_)
    throw UsageError("StoreSamples::read_values: bad range");
  if (!reader_ || first % reader_rows_ != 0 || (count % reader_rows_ != 0 && first + count != size_)) {
    store_->read_samples(name_, first, count, {}, out);
    return;
  }
  // Whole reader blocks: decoded on every thread at once.
  const std::size_t b0 = first / reader_rows_, nb = (count + reader_rows_ - 1) / reader_rows_;
  parallel_for(
      nb, [] { return store::BlockReader::RawBlock(); },
      [&](std::size_t i, store::BlockReader::RawBlock& raw) {
        reader_->read_raw(b0 + i, raw);
        std::copy(raw.values.begin(), raw.values.end(), out.begin() + std::ptrdiff_t(i * reader_rows_ * bands_));
      });
}

}  // namespace specula::acquire
