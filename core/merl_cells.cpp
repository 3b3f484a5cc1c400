#include "specula/core/merl_cells.h"

#include "specula/core/brdf_geometry.h"
#include "specula/core/parallel.h"

namespace specula::brdf {

const std::vector<std::uint32_t>& merl_valid_cells() {
  static const std::vector<std::uint32_t> cells = [] {
    std::vector<std::vector<std::uint32_t>> rows(kMerlThetaH);
    parallel_for(rows.size(), [&](std::size_t th) {
      Eigen::Vector3d wi, wo;
      for (int td = 0; td < kMerlThetaD; ++td) {
        const MerlCentres row(int(th), td);
        for (int pd = 0; pd < kMerlPhiD; ++pd) {
          row.directions(pd, wi, wo);  // merl_cell_valid, with the row's shared trigonometry
          if (wi.z() > 0 && wo.z() > 0) rows[th].push_back(std::uint32_t(merl_index({int(th), td, pd})));
        }
      }
    });
    std::size_t total = 0;
    for (const auto& r : rows) total += r.size();
    std::vector<std::uint32_t> all;
    all.reserve(total);
    for (const auto& r : rows) all.insert(all.end(), r.begin(), r.end());
    return all;
  }();
  return cells;
}

}  // namespace specula::brdf
