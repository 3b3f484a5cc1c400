#pragma once
// How far an acquisition is from a simulated capture's known truth: light directions against the manifest's, and
// the extracted samples against the material's model.
#include <functional>
#include <string>

#include "specula/acquire/capture.h"
#include "specula/acquire/pipeline.h"
#include "specula/core/brdf_models.h"
#include "specula/store/store.h"

namespace specula::acquire {

/// Calls fn(angles, values) for every sample of `name` in order, read in blocks (angles: 4 values, values: bands).
void for_each_sample(const store::Store& s, const std::string& name,
                     const std::function<void(const double* angles, const float* values)>& fn);

/// Mean and largest angle (degrees) between calibrated light directions and the manifest's truth; {-1, -1} when the
/// capture has no truth for them.
std::pair<double, double> light_direction_error(const Capture& capture, const Calibration& c);

/// Median of |sample / model - 1| and of sample / model over every band of the samples of `name` whose model value is
/// above 1e-3 (at most about a million samples, evenly spaced); {-1, -1} when no value qualifies.
std::pair<double, double> sample_error(const store::Store& s, const std::string& name,
                                       const brdf::SpectralModel& model);

}  // namespace specula::acquire
