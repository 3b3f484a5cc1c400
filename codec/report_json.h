#pragma once
// The reports codec's runs produce, as JSON objects (keys in a fixed order) for `--json` output and Python: one
// definition of each report's fields, whoever prints it.
#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace specula::codec {

struct GridDiff;
struct SpcBasis;
struct SpcBoundedOptions;
struct SpcKReport;
struct SpcReport;
struct SpcTarget;
struct SpcTargetReport;

/// diff_grids' result under the environment described by `environment` on a `size`-pixel sphere: environment, cells,
/// only_a, only_b, rms, max_abs, rel_rms_cos, de00_mean, de00_p95, de00_max, size (no per-pixel maps).
nlohmann::ordered_json grid_diff_json(const GridDiff& d, std::string_view environment, std::size_t size);

/// An encoding's report: method and the written file's format_version, the target search when
/// `target` and `target_report` are given, step, basis, k, max_error, byte counts, ratio, bits_per_cell, valid_cells,
/// seconds and encode_mb_per_s of a run that took `seconds`, the errors, magnitude_scale, magnitude_step,
/// shape_step and OpenMP threads.
/// Rounded as printed before: ratio to 3 decimals, bits per cell and reached ΔE00 to 4, seconds to 6, MB/s to 1.
nlohmann::ordered_json spc_encode_json(const SpcReport& report, const SpcBasis& basis, const SpcBoundedOptions* bounded,
                                       const SpcTarget* target, const SpcTargetReport* target_report,
                                       std::uint32_t format_version, double seconds);

/// A search over k (encode_spc_choosing_k): the k chosen and every candidate in the order tried, each with k, searched
/// (false: a floor probe, with floor_met), and for a search reached, first_step, step and bytes.
nlohmann::ordered_json spc_k_search_json(const SpcKReport& report);

}  // namespace specula::codec
