#include "specula/acquire/peak_cap.h"

#include <algorithm>

namespace specula::acquire {
namespace {

constexpr int kCapWindow = 8;  // theta_d rows on either side

}  // namespace

UnseenCap unseen_cap(const PriorObservations& obs) {
  UnseenCap cap;
  cap.fill(brdf::kMerlThetaH);
  const auto& cells = valid_cells();
  for (const std::uint32_t v : obs.cell) {
    const brdf::MerlCell c = brdf::merl_cell(std::size_t(cells[v]));
    cap[std::size_t(c.theta_d)] = std::min(cap[std::size_t(c.theta_d)], c.theta_h);
  }
  // The lowest over a window of theta_d rows: a row between two lights' rows (up to 16 rows apart: 10 lights 16
  // degrees apart) holds no sample, or only samples far off the peak from a neighbouring light's spread.
  const UnseenCap first = cap;
  for (int j = 0; j < brdf::kMerlThetaD; ++j)
    for (int d = std::max(0, j - kCapWindow); d <= std::min(brdf::kMerlThetaD - 1, j + kCapWindow); ++d)
      cap[std::size_t(j)] = std::min(cap[std::size_t(j)], first[std::size_t(d)]);
  return cap;
}

bool in_unseen_cap(const UnseenCap& cap, std::size_t cell) {
  const brdf::MerlCell c = brdf::merl_cell(cell);
  return c.theta_h < cap[std::size_t(c.theta_d)];
}

}  // namespace specula::acquire
