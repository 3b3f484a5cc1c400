#pragma once
// A store's samples as a brdf::SampleSource for the scattered-data resampler (core/brdf_resample.h), read in blocks
// of whole storage chunks.
#include <memory>
#include <string>

#include "specula/core/brdf_resample.h"

namespace specula::store {
class Store;
class BlockReader;
}  // namespace specula::store

namespace specula::acquire {

/// Samples `name` of a store, read in blocks of whole storage chunks (about 32 MiB of values); the chunks of a
/// block are decompressed on all threads (store/block_reader.h).
class StoreSamples final : public brdf::SampleSource {
 public:
  /// InputError (listing the samples) when the store has no samples `name`.
  StoreSamples(const store::Store& store, std::string name);
  ~StoreSamples() override;
  std::size_t size() const override { return size_; }
  std::size_t bands() const override { return bands_; }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override;
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override;
  std::size_t block_rows() const override { return block_rows_; }
  bool has_variance() const override { return variance_; }
  void read_variance(std::size_t first, std::size_t count, std::span<float> out) const override;

 private:
  std::unique_ptr<store::Store> store_;
  std::unique_ptr<store::BlockReader> reader_;
  std::string name_;
  std::size_t size_ = 0, bands_ = 0, block_rows_ = 0, reader_rows_ = 0;
  bool variance_ = false;
};

}  // namespace specula::acquire
