#pragma once
// The report of a filter design (acquire/filter_design.h) as `specula filters design --json` prints it and the Python
// module returns it.
#include <nlohmann/json_fwd.hpp>

#include "specula/acquire/filter_design.h"

namespace specula::acquire {

/// The design `d` made with options `o`: filters (count), method, noise, ridge, solve, exposure, min_throughput,
/// throughput (each filter's white reading over an open filter's), roughness, and training and held_out, each
/// spectra (their name), count, rms_mean, rms_median, rms_max and noise_rms.
nlohmann::ordered_json filter_design_json(const FilterDesign& d, const FilterDesignOptions& o);

}  // namespace specula::acquire
