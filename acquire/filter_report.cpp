#include "specula/acquire/filter_report.h"

#include <nlohmann/json.hpp>

namespace specula::acquire {
namespace {

nlohmann::ordered_json error_json(const FilterError& e, const std::string& name) {
  return {{"spectra", name},      {"count", e.spectra},      {"rms_mean", e.rms_mean}, {"rms_median", e.rms_median},
          {"rms_max", e.rms_max}, {"noise_rms", e.noise_rms}};
}

}  // namespace

nlohmann::ordered_json filter_design_json(const FilterDesign& d, const FilterDesignOptions& o) {
  nlohmann::ordered_json j;
  j["filters"] = d.filters.size();
  j["method"] = o.method == FilterMethod::nmf ? "nmf" : "optimal";
  j["noise"] = o.noise;
  j["ridge"] = o.ridge;
  j["colour_weight"] = o.colour_weight;
  j["solve"] = o.solve == FilterSolve::wiener ? "wiener" : "ridge";
  j["exposure"] = o.per_filter_exposure ? "per filter" : "equal";
  j["min_throughput"] = o.min_throughput;
  j["throughput"] = filter_throughput(d.filters, d.bands, design_sensitivity(o.light_kelvin));
  j["roughness"] = filter_roughness(d.filters);
  j["training"] = error_json(d.training, d.training_name);
  j["held_out"] = error_json(d.held_out, d.held_out_name);
  return j;
}

}  // namespace specula::acquire
