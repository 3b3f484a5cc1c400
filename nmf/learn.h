#pragma once
// NMF of a selection of one or more stores (reference §7.4) as `specula nmf` and specula.nmf() run it: the basis
// with what it was learned from and the run's settings, and the conventions for its name and checkpoint.
#include <filesystem>
#include <string>
#include <vector>

#include "specula/nmf/nmf.h"
#include "specula/store/basis.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::nmf {

/// A learned NMF basis and the run that found it.
struct LearnedBasis {
  store::Basis basis;  ///< the best restart's components and weights, with source and provenance
  NmfResult result;
  std::size_t bands = 0;
};

/// "nndsvd" or "random".
std::string init_name(Init init);
/// The name a basis of k components is saved under when none is given: nmf<k>.
std::string default_basis_name(std::size_t k);
/// Where the checkpoint of a run saving basis `name` in the store `output` is kept: <output>.nmf-<name>.checkpoint.
std::filesystem::path default_checkpoint(const std::filesystem::path& output, const std::string& name);

/// Factors every valid spectrum of `selection` in `stores` (read as one database) by factorize() and returns the best
/// basis with its source, the stores' paths and the settings and errors of the run as provenance. Throws as
/// factorize().
LearnedBasis learn_basis(const std::vector<store::Store>& stores, const store::Selection& selection,
                         const NmfOptions& options, const Collective& ranks = single_process());

}  // namespace specula::nmf
