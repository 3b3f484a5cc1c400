#include "specula/codec/rgl_target.h"

#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_tensor.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/error.h"

namespace specula::codec {

namespace {

// Exports at `s`, judges the import and records the trial; true when it meets the target.
bool attempt(const store::Grid& grid, const RglExportSettings& s, const RglTarget& target, const LightingSuite& suite,
             RglTargetReport& report, RglBsdf& out) {
  const auto* source = grid.parameterisation ? &*grid.parameterisation : nullptr;
  const RglParameterisation used = rgl_parameterisation_used(source, s);
  out = export_rgl(grid, s);
  const SuiteDiff d = suite_diff(grid, rgl_to_grid(out, "export"), suite);
  RglTargetTrial t{out.theta_i.size(), out.resolution, used, tensor_file_bytes(to_tensor(out)).size(),
                   d.de00_mean,        d.de00_p95,     false};
  t.met = d.de00_mean <= target.de00_mean && d.de00_p95 <= target.de00_p95;
  report.trials.push_back(t);
  report.reached = t.met;
  return t.met;
}

}  // namespace

RglBsdf export_rgl_judged(const store::Grid& grid, const RglExportSettings& settings, const LightingSuite& suite,
                          RglParameterisation& used, const Eigen::Matrix<double, 3, Eigen::Dynamic>* rgb) {
  const auto* source = grid.parameterisation ? &*grid.parameterisation : nullptr;
  used = rgl_parameterisation_used(source, settings);
  RglExportSettings s = settings;
  if (source && !s.theta_i) s.theta_i = source->theta_i.size();  // both candidates at the source's size
  if (source && !s.resolution) s.resolution = source->resolution;
  RglBsdf spectral;
  if (settings.parameterisation == RglParameterisation::automatic && used == RglParameterisation::source) {
    s.parameterisation = RglParameterisation::source;
    RglBsdf on_source = export_rgl(grid, s);
    s.parameterisation = RglParameterisation::estimate;
    RglBsdf estimated = export_rgl(grid, s);
    const double a = suite_diff(grid, rgl_to_grid(on_source, "export"), suite).de00_mean;
    const double b = suite_diff(grid, rgl_to_grid(estimated, "export"), suite).de00_mean;
    used = a <= b ? RglParameterisation::source : RglParameterisation::estimate;
    spectral = a <= b ? std::move(on_source) : std::move(estimated);
  }
  s.parameterisation = used;
  if (rgb) return export_rgl(grid_to_merl(grid, *rgb).brdf, s, source);
  return spectral.theta_i.empty() ? export_rgl(grid, s) : spectral;
}

RglBsdf export_rgl_to_target(const store::Grid& grid, const RglExportSettings& settings, const RglTarget& target,
                             const LightingSuite& suite, RglTargetReport& report) {
  if (!(target.de00_mean > 0) || !(target.de00_p95 > 0))
    throw UsageError("RGL export: the target's dE00 mean and 95th percentile must be positive");
  report = {};
  RglBsdf best;
  const auto* source = grid.parameterisation ? &*grid.parameterisation : nullptr;
  if (rgl_parameterisation_used(source, settings) == RglParameterisation::source) {
    if (attempt(grid, settings, target, suite, report, best) ||
        settings.parameterisation == RglParameterisation::source)
      return best;
  }
  const std::size_t theta_i = settings.theta_i ? settings.theta_i : 8,
                    res = settings.resolution ? settings.resolution : 32;
  const std::size_t own = theta_i * res * res;
  for (std::size_t k = 0; k < kRglTargetLadder.size(); ++k) {
    const auto [ladder_theta_i, resolution] = kRglTargetLadder[k];
    if (ladder_theta_i * resolution * resolution < own && k + 1 < kRglTargetLadder.size()) continue;
    RglExportSettings s = settings;
    s.theta_i = ladder_theta_i;
    s.resolution = resolution;
    s.parameterisation = RglParameterisation::estimate;
    if (attempt(grid, s, target, suite, report, best)) break;
  }
  return best;
}

}  // namespace specula::codec
