#pragma once
// Named analytic spectral materials (core/brdf_models.h) with parameters that vary smoothly with wavelength:
// test and demonstration material with known ground truth for grids (synth-brdf) and scattered samples
// (synth-samples), plus the grey models of the reference's resampling study (§5.4).
#include <map>
#include <memory>
#include <string>

#include "specula/core/brdf_models.h"

namespace specula::brdf {

/// Every material's name and a one-line description.
const std::map<std::string, std::string>& material_catalogue();
/// Material `name` on grid g; UsageError naming the choices for an unknown name.
std::unique_ptr<SpectralModel> make_material(const std::string& name, const WavelengthGrid& g);

}  // namespace specula::brdf
