#include "specula/stats/learn_pca.h"

#include <fmt/format.h>

#include <chrono>

#include "specula/core/error.h"
#include "specula/stats/moments.h"
#include "specula/stats/pca.h"
#include "specula/store/learned_basis.h"

namespace specula::stats {

LearnedPca learn_pca(const std::vector<store::Store>& stores, const store::Selection& selection, std::size_t k,
                     const Collective& ranks) {
  const store::BlockReader reader(stores, selection);
  if (k > reader.bands()) throw UsageError(fmt::format("pca: k = {}: the data has {} bands", k, reader.bands()));
  if (reader.spectra() < 2)
    throw InputError(fmt::format("{}: the selection holds {} valid spectra; PCA needs at least two",
                                 stores.front().label(), reader.spectra()));
  const auto t0 = std::chrono::steady_clock::now();
  const Moments moments = stream_moments(reader, ranks);
  const auto t1 = std::chrono::steady_clock::now();
  LearnedPca out;
  out.basis = pca_basis(moments, reader.wavelengths(), k);
  out.stream_seconds = std::chrono::duration<double>(t1 - t0).count();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.basis.source = store::selection_source(reader, selection);
  out.basis.provenance.source_file = store::source_files(stores);
  out.basis.provenance.importer = "pca";
  return out;
}

}  // namespace specula::stats
