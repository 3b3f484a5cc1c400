#pragma once
// A store's description with its calibrations: what `specula info --json` prints.
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "specula/acquire/pipeline.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// "delta" or "factored".
const char* spectral_model_name(SpectralModel model);
/// The calibration `name`'s kind, name, spectral model and number of lights.
nlohmann::ordered_json calibration_json(const std::string& name, const Calibration& c);
/// store::store_json() with every calibration of the store appended to its objects.
nlohmann::ordered_json store_info_json(const store::Store& store);

}  // namespace specula::acquire
