#include "specula/acquire/peak_cap.h"

namespace specula::acquire {

UnseenCap unseen_cap(const PriorObservations& obs) {
  UnseenCap cap;
  cap.fill(brdf::kMerlThetaH);
  const auto& cells = valid_cells();
  for (const std::uint32_t v : obs.cell) {
    const brdf::MerlCell c = brdf::merl_cell(std::size_t(cells[v]));
    cap[std::size_t(c.theta_d)] = std::min(cap[std::size_t(c.theta_d)], c.theta_h);
  }
  return cap;
}

bool in_unseen_cap(const UnseenCap& cap, std::size_t cell) {
  const brdf::MerlCell c = brdf::merl_cell(cell);
  return c.theta_h < cap[std::size_t(c.theta_d)];
}

}  // namespace specula::acquire
