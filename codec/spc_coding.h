#pragma once
// One coding as `specula encode` and specula.spc_encode ask for it: a basis (the input's own spectra or a learned
// one, k given or chosen by the target), one method (bounded, transform at a step or to a target, samples), and
// what the coding measured.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "specula/codec/spc.h"
#include "specula/codec/spc_target.h"
#include "specula/codec/suite.h"
#include "specula/store/basis.h"

namespace specula::codec {

/// Where a coding's basis comes from: the input's own spectra (no learned basis, extra 0) or a learned PCA or NMF
/// basis cut to k spectra and extended by `extra` spectra of what it leaves of the input; `reference` names it.
struct SpcBasisSource {
  std::shared_ptr<const store::Basis> learned;
  std::string reference = "self";
  std::size_t extra = 0;
};

/// The source "self" or "STORE.h5:BASIS" names (the basis read from its store); UsageError otherwise, naming the
/// parameter `what`.
SpcBasisSource read_basis_source(const std::string& spec, std::size_t extra, const std::string& what);

/// A target search: the target and the lighting suite that judges it.
struct SpcTargetSearch {
  SpcTarget target;
  const LightingSuite& suite;
};

/// What a coding made and measured.
struct SpcCoding {
  std::vector<std::uint8_t> bytes;
  SpcBasis basis;
  SpcReport report;
  std::optional<SpcTargetReport> target;  ///< when coded to a target
  std::optional<SpcKReport> k_search;     ///< when the target chose k
  std::size_t max_k = 0;                  ///< the largest k the source offers for this input
};

/// `grid` on k spectra of `source` by the bounded method (format 1). UsageError for k 0, extra with the grid's own
/// spectra, or a k the source lacks.
SpcCoding code_grid(const store::Grid& grid, const SpcBasisSource& source, std::size_t k,
                    const SpcBoundedOptions& options, const std::string& label);
/// `grid` by the transform method: at options.step without a target; with one, at the coarsest step meeting it
/// (encode_spc_to_target), and with k 0 at the k of the smallest file meeting it (encode_spc_choosing_k).
/// UsageError for k 0 without a target, and as above.
SpcCoding code_grid(const store::Grid& grid, const SpcBasisSource& source, std::size_t k,
                    const SpcTransformOptions& options, const SpcTargetSearch* target, const std::string& label);
/// Scattered samples by the samples method (format 4) as code_grid does a grid, judged against the grid they
/// resample to under options.rule (k of the rule resolved, not 0); their own spectra count each sample once, and
/// `extra` spectra come from that grid.
SpcCoding code_samples(const SpcSampleSet& samples, const SpcBasisSource& source, std::size_t k,
                       const SpcSamplesOptions& options, const SpcTargetSearch* target, const std::string& label);

/// spc_encode_json of a coding (bounded: the options of a bounded coding, else null), with k_search when the target
/// chose k.
nlohmann::ordered_json spc_coding_json(const SpcCoding& coding, const SpcBoundedOptions* bounded,
                                       const SpcTarget* target, double seconds, const std::string& label);

}  // namespace specula::codec
