#pragma once
// Pictures of a comparison of two BRDF grids (brdf-diff's --panel and --heatmap): the two renderings and their
// CIEDE2000 map side by side, under one environment or under the lighting suite's worst condition.
#include <cstddef>
#include <span>

#include "specula/core/preview.h"

namespace specula::codec {

class LightingSuite;
struct SphereRenders;
struct SuiteDiff;
struct SuiteRenders;

/// Renderings 0 and 1 of `renders` (linear_srgb, then encode_srgb8 at exposure 0) and the per-pixel CIEDE2000 map
/// `de00` (size x size; 0 to 2 across the heat ramp) side by side: 3 size x size pixels of sRGB8, pixels off the
/// sphere dark grey (24); with map_only the map alone. InputError as linear_srgb; UsageError if de00 is not
/// size x size.
Picture diff_panel(const SphereRenders& renders, std::span<const float> de00, bool map_only);

/// As diff_panel for the suite's worst condition of `d` (suite.compare with keep_maps) from the renderings `a` and `b`
/// that were compared; UsageError without per-pixel maps.
Picture suite_panel(const LightingSuite& suite, const SuiteRenders& a, const SuiteRenders& b, const SuiteDiff& d,
                    bool map_only);

}  // namespace specula::codec
