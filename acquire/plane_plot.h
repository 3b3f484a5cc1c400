#pragma once
// What the incidence-plane plots (figures 5.5-5.7, 5.17) and the spectral-calibration plot (figures 4.6-4.9) draw,
// as whitespace-separated tables, one point a line (gnuplot's data blocks). Angles in degrees, BRDF values as cube
// roots (the reference's scale for peaks and tails together).
#include <span>
#include <string>
#include <vector>

#include "specula/acquire/incidence.h"
#include "specula/core/brdf_models.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

struct TargetReport;

/// The samples (angles n x 4, radians; values n x bands) within eps of the incidence plane at theta_i, in order,
/// valued at `band`: incidence_plane_points() for samples in memory. UsageError for sizes or a band past the last.
std::vector<PlanePoint> incidence_plane_points(std::span<const double> angles, std::span<const float> values,
                                               std::size_t bands, double theta_i, double eps, std::size_t band);

/// "theta_o cbrt(max(0, value))" per point, theta_o in degrees to 3 decimals, values to 5 significant digits.
std::string plane_points_table(std::span<const PlanePoint> points);

/// The model along the incidence plane at theta_i (radians), theta_o from -89.5 to 89.5 degrees in steps of 0.5
/// (negative: the light's side): "theta_o cbrt(max(0, f))" at `band` (< the model's bands).
std::string model_plane_table(const brdf::SpectralModel& model, double theta_i, std::size_t band);

/// As model_plane_table() for a one-band model, with the grid's value between: "theta_o recon cbrt(f)", recon the
/// cube root of r's reconstruction (one band) at the centre of the MERL cell the grid lookup reads, NaN where r
/// has no data there.
std::string grid_plane_table(const brdf::Resampler& r, const brdf::SpectralModel& model, double theta_i);

/// "nm known recovered factored" per band of a calibration target: recovered is the filters' recovery when there
/// is one, else the delta model's; factored is NaN when there is none. `bands` are the tuning wavelengths.
std::string target_table(const TargetReport& target, std::span<const double> bands);

}  // namespace specula::acquire
