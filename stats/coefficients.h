#pragma once
// Coefficient maps (reference eq 7.2, §7.4): the spectra of whole images projected onto a basis (stats/project.h)
// and written as /coefficients/<name> datasets of a store, streamed block by block so that memory holds a few
// blocks, never an image. `specula coefficients` calls it and plots the maps; the Python module can too.
// Placement: stats, beside the one Projector it applies; it reads through store::BlockReader and writes through a
// store::StoreWriter, both of the library below.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "specula/stats/project.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::stats {

/// One coefficient map as written: its image and the reconstruction error of its valid pixels from the
/// coefficients (in double precision, before they are stored as float32).
struct CoefficientMap {
  std::string name, image;
  std::size_t height = 0, width = 0;
  std::uint64_t valid = 0;  ///< valid pixels of the image
  double sum_sq = 0;        ///< ||X||_F^2 over the valid pixels
  ProjectionError error;    ///< of the reconstruction X' from the coefficients
  /// ||X - X'||_F / ||X||_F over the valid pixels; 0 for an image without signal.
  double relative_error() const;
};

/// What the maps record besides their data.
struct CoefficientMapsOptions {
  std::string basis_name;        ///< the basis's name in the store, stored with each map
  store::Provenance provenance;  ///< of every map
};

/// Creates map names[i] of source image i of `reader` (images of `store`, on the basis's wavelengths) in `writer`,
/// projects every block on all threads and writes the rows in block order, so the maps and errors do not depend on
/// the thread count; the caller commits. Progress shown, Interrupted between waves of blocks. Returns one
/// CoefficientMap per image, in reader order. UsageError unless there is one name per image; InputError when the
/// reader's wavelengths differ from the basis's or a source is not an image.
std::vector<CoefficientMap> write_coefficient_maps(const store::Store& store, const store::BlockReader& reader,
                                                   const Projector& projector, std::span<const std::string> names,
                                                   const CoefficientMapsOptions& options, store::StoreWriter& writer);

}  // namespace specula::stats
