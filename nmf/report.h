#pragma once
// The report of an NMF run as one JSON object: what `specula nmf --json` prints and specula.nmf() returns.
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <span>
#include <string>

#include "specula/nmf/learn.h"

namespace specula::nmf {

/// What the caller of learn_basis() knows about the run besides its result.
struct RunContext {
  std::string store;                    ///< the first input store
  std::optional<std::string> basis;     ///< the name the basis was saved under (null when not saved)
  std::optional<std::string> output;    ///< the store it was saved in (null when not saved)
  double seconds = 0;                   ///< wall time of the run
  std::span<const EpochReport> epochs;  ///< every epoch's report, in order
  std::size_t ranks = 1;
};

/// The run as one JSON object: store, basis, output, k, n, bands, the best restart's errors, epochs and history
/// (with seconds), every restart, passes, negatives, warm-up, weights, components, threads and ranks.
nlohmann::ordered_json report_json(const LearnedBasis& learned, const RunContext& context);

}  // namespace specula::nmf
