#pragma once
// PCA of a selection of one or more stores (reference §7.3) as `specula pca` and specula.pca() run it: the checks,
// one exact streaming pass, the eigen-decomposition and the basis with what it was learned from.
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "specula/core/collective.h"
#include "specula/store/basis.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::stats {

/// A learned PCA basis and the time it took.
struct LearnedPca {
  store::Basis basis;         ///< with source, provenance (the stores' paths, importer "pca")
  double seconds = 0;         ///< streaming and decomposition
  double stream_seconds = 0;  ///< streaming alone
};

/// PCA of every valid spectrum of `selection` in `stores` (read as one database), keeping k components (0: all);
/// every rank streams its share. Throws UsageError when k exceeds the bands, InputError with fewer than two spectra.
LearnedPca learn_pca(const std::vector<store::Store>& stores, const store::Selection& selection, std::size_t k,
                     const Collective& ranks = single_process());

/// The run as one JSON object (what `specula pca --json` prints): store, basis, output, n, bands, wavelengths, mean,
/// eigenvalues, explained_variance_ratio, components (k), seconds, stream_seconds, spectra_per_s, threads, ranks.
/// `store` is the first input store, `name` and `output` where the basis was saved.
nlohmann::ordered_json pca_report_json(const LearnedPca& learned, const std::string& store, const std::string& name,
                                       const std::string& output, std::size_t ranks);

}  // namespace specula::stats
