#include "specula/codec/report_json.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "specula/codec/diff.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_target.h"

namespace specula::codec {
namespace {

using Json = nlohmann::ordered_json;

// v rounded to `decimals` places, as "{:.Nf}" printed it.
double rounded(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  return std::isfinite(v) ? std::round(v * scale) / scale : v;
}

}  // namespace

Json grid_diff_json(const GridDiff& d, std::string_view environment, std::size_t size) {
  return {{"environment", environment},
          {"cells", d.cells},
          {"only_a", d.only_a},
          {"only_b", d.only_b},
          {"rms", d.rms},
          {"max_abs", d.max_abs},
          {"rel_rms_cos", d.rel_rms_cos},
          {"de00_mean", d.de00_mean},
          {"de00_p95", d.de00_p95},
          {"de00_max", d.de00_max},
          {"size", size}};
}

Json spc_encode_json(const SpcReport& report, const SpcBasis& basis, const SpcBoundedOptions* bounded,
                     const SpcTarget* target, const SpcTargetReport* target_report, std::uint32_t format_version,
                     double seconds) {
  const bool transform = bounded == nullptr;
  Json j;
  j["method"] = format_version == 4 ? "samples" : transform ? "transform" : "bounded";
  j["format_version"] = format_version;
  if (target && target_report)
    j["target"] = {{"de00_mean", target->de00_mean},
                   {"de00_p95", target->de00_p95},
                   {"reached", target_report->reached},
                   {"trials", target_report->trials},
                   {"step", target_report->step},
                   {"reached_de00_mean", rounded(target_report->de00_mean, 4)},
                   {"reached_de00_p95", rounded(target_report->de00_p95, 4)},
                   {"condition_mean", target->condition_mean},
                   {"worst_condition", target_report->worst_condition},
                   {"worst_de00_mean", rounded(target_report->worst_mean, 4)},
                   {"measure", "lighting suite"}};
  j["step"] = transform ? report.magnitude_step : 0.0;
  j["basis"] = basis.reference;
  j["k"] = basis.k();
  j["max_error"] = transform ? 0.0 : bounded->max_error;
  j["input_bytes"] = report.input_bytes;
  j["output_bytes"] = report.output_bytes;
  j["ratio"] = rounded(double(report.input_bytes) / double(report.output_bytes), 3);
  const double cells = double(std::max<std::uint64_t>(report.valid_cells, 1));
  j["bits_per_cell"] = rounded(8.0 * double(report.output_bytes) / cells, 4);
  j["valid_cells"] = report.valid_cells;
  j["seconds"] = rounded(seconds, 6);
  j["encode_mb_per_s"] = rounded(double(report.input_bytes) / 1e6 / seconds, 1);
  j["rms_error"] = report.rms_error;
  j["max_abs_error"] = report.max_abs_error;
  j["max_shape_residual"] = report.max_shape_residual;
  j["max_quantisation_error"] = report.max_quantisation_error;
  j["magnitude_scale"] = report.magnitude_scale;
  j["magnitude_step"] = report.magnitude_step;
  j["shape_step"] = report.shape_step;
  j["threads"] = omp_get_max_threads();
  return j;
}

Json spc_k_search_json(const SpcKReport& report) {
  Json candidates = Json::array();
  for (const SpcKCandidate& c : report.candidates) {
    Json j = {{"k", c.k}, {"searched", c.searched}};
    if (!c.searched) j["floor_met"] = c.floor_met;
    if (c.searched)
      j.update(Json{{"reached", c.reached}, {"first_step", c.first_step}, {"step", c.step}, {"bytes", c.bytes}});
    candidates.push_back(std::move(j));
  }
  return {{"chosen_k", report.k}, {"candidates", std::move(candidates)}};
}

}  // namespace specula::codec
