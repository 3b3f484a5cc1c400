#include "specula/codec/rgl_target.h"

#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_tensor.h"
#include "specula/core/error.h"

namespace specula::codec {

RglBsdf export_rgl_to_target(const store::Grid& grid, const RglExportSettings& settings, const RglTarget& target,
                             const LightingSuite& suite, RglTargetReport& report) {
  if (!(target.de00_mean > 0) || !(target.de00_p95 > 0))
    throw UsageError("RGL export: the target's dE00 mean and 95th percentile must be positive");
  report = {};
  const std::size_t own = settings.theta_i * settings.resolution * settings.resolution;
  RglBsdf best;
  for (std::size_t k = 0; k < kRglTargetLadder.size(); ++k) {
    const auto [theta_i, resolution] = kRglTargetLadder[k];
    if (theta_i * resolution * resolution < own && k + 1 < kRglTargetLadder.size()) continue;
    RglExportSettings s = settings;
    s.theta_i = theta_i;
    s.resolution = resolution;
    best = export_rgl(grid, s);
    const SuiteDiff d = suite_diff(grid, rgl_to_grid(best, "export"), suite);
    RglTargetTrial t{theta_i, resolution, tensor_file_bytes(to_tensor(best)).size(), d.de00_mean, d.de00_p95, false};
    t.met = d.de00_mean <= target.de00_mean && d.de00_p95 <= target.de00_p95;
    report.trials.push_back(t);
    if (t.met) {
      report.reached = true;
      break;
    }
  }
  return best;
}

}  // namespace specula::codec
