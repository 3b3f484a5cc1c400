#include "specula/acquire/info_json.h"

#include <nlohmann/json.hpp>

#include "specula/store/info_json.h"

namespace specula::acquire {

const char* spectral_model_name(SpectralModel model) { return model == SpectralModel::delta ? "delta" : "factored"; }

nlohmann::ordered_json calibration_json(const std::string& name, const Calibration& c) {
  return {{"kind", "calibration"},
          {"name", name},
          {"spectral_model", spectral_model_name(c.spectral.model)},
          {"lights", c.light_dirs.size()}};
}

nlohmann::ordered_json store_info_json(const store::Store& s) {
  nlohmann::ordered_json j = store::store_json(s);
  for (const auto& n : s.objects("acquire")) j["objects"].push_back(calibration_json(n, read_calibration(s, n)));
  return j;
}

}  // namespace specula::acquire
