#include "specula/core/merl_cells.h"

#include <array>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/parallel.h"

namespace specula::brdf {

namespace {

// How far a cell's directions may be from the horizon and still be decided by the short formula below: its
// rounding is a few 1e-16, and closer cells are decided as merl_cell_valid decides them.
constexpr double kHorizonMargin = 1e-9;

}  // namespace

// A cell's directions are the difference vector d = (sin td cos pd, sin td sin pd, cos td), and d mirrored about the
// normal, both turned by th about the binormal: their heights are cos th cos td -/+ sin th sin td cos pd. The full
// turn (MerlCentres::directions) is taken only where a height lies within kHorizonMargin of 0, so the list is
// merl_cell_valid's, at a small part of the cost of turning every cell (once per process, but 44 ms of a decode).
const std::vector<std::uint32_t>& merl_valid_cells() {
  static const std::vector<std::uint32_t> cells = [] {
    std::array<double, kMerlPhiD> turn{};  // |cos| of each phi_d centre
    for (int pd = 0; pd < kMerlPhiD; ++pd)
      turn[std::size_t(pd)] = std::abs(std::cos(merl_cell_centre({0, 0, pd}).phi_d));
    std::vector<std::vector<std::uint32_t>> rows(kMerlThetaH);
    parallel_for(rows.size(), [&](std::size_t th) {
      Eigen::Vector3d wi, wo;
      for (int td = 0; td < kMerlThetaD; ++td) {
        const HalfDiff centre = merl_cell_centre({int(th), td, 0});
        const double level = std::cos(centre.theta_h) * std::cos(centre.theta_d);
        const double tilt = std::sin(centre.theta_h) * std::sin(centre.theta_d);
        for (int pd = 0; pd < kMerlPhiD; ++pd) {
          const double lowest = level - tilt * turn[std::size_t(pd)];  // the lower of the two heights
          bool valid = lowest > kHorizonMargin;
          if (std::abs(lowest) <= kHorizonMargin) {
            MerlCentres(int(th), td).directions(pd, wi, wo);
            valid = wi.z() > 0 && wo.z() > 0;
          }
          if (valid) rows[th].push_back(std::uint32_t(merl_index({int(th), td, pd})));
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
