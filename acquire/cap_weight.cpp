#include "specula/acquire/cap_weight.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>

#include "specula/acquire/peak_cap.h"
#include "specula/acquire/scan_holdout.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

void check_ladder(const std::vector<double>& ladder) {
  if (ladder.empty()) throw UsageError("cap weight: the ladder of weights is empty");
  for (std::size_t l = 0; l < ladder.size(); ++l)
    if (!(ladder[l] >= 0 && ladder[l] <= 1) || (l > 0 && ladder[l] <= ladder[l - 1]))
      throw UsageError("cap weight: the ladder of weights must ascend strictly within [0, 1]");
}

// True when MERL cell `cell` lies in its theta_d row's rehearsal rows [C, min(2 C, 90)), 0 < C < 90.
bool in_rehearsal(const UnseenCap& cap, std::size_t cell) {
  const brdf::MerlCell m = brdf::merl_cell(cell);
  const int c = cap[std::size_t(m.theta_d)];
  return c > 0 && c < brdf::kMerlThetaH && m.theta_h >= c && m.theta_h < std::min(2 * c, brdf::kMerlThetaH);
}

}  // namespace

CapWeightChoice choose_cap_weight(const brdf::SampleSource& src, const BrdfPrior& prior,
                                  const ComponentSource& components, const PriorResampleOptions& o,
                                  const CapWeightOptions& c) {
  check_ladder(c.ladder);
  if (o.residuals) throw UsageError("cap weight: chosen for the blend only, not the residuals form");
  const auto t0 = std::chrono::steady_clock::now();
  const auto& cells = valid_cells();
  const std::vector<std::int32_t> slots = sample_slots(src);
  PriorObservations seen;  // the observed cells, for the cap's rule
  {
    std::vector<std::uint8_t> hit(cells.size(), 0);
    for (const std::int32_t v : slots)
      if (v >= 0) hit[std::size_t(v)] = 1;
    for (std::size_t i = 0; i < hit.size(); ++i)
      if (hit[i]) seen.cell.push_back(std::uint32_t(i));
  }
  const UnseenCap cap = unseen_cap(seen);
  CapWeightChoice out;
  out.cap_rows.assign(cap.begin(), cap.end());
  std::vector<std::uint8_t> held(slots.size(), 0);
  for (std::size_t s = 0; s < slots.size(); ++s)
    if (slots[s] >= 0 && in_rehearsal(cap, cells[std::size_t(slots[s])])) {
      held[s] = 1;
      ++out.held_samples;
    }
  const std::vector<PriorObservations> parts = cell_means(src, o.fit.weights != PriorWeights::scatter, held, 2);
  out.held_cells = parts[1].cell.size();
  if (parts[1].cell.empty() || parts[0].cell.empty()) {
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  const std::size_t b = src.bands();
  std::vector<float> fitted(b * brdf::kMerlCells, -1.0f);
  fit_prior(prior, components, parts[0], o.fit, fitted);
  if (o.ceiling) {
    std::vector<std::uint8_t> rehearsal(brdf::kMerlCells, 0);
    for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) rehearsal[cell] = in_rehearsal(cap, cell);
    bound_by_ceiling(prior, rehearsal, fitted);
  }
  out.epsilon = judge_epsilon(parts[0], prior, b);
  const KeptSamples kept(src, held);
  std::vector<float> kd(b * brdf::kMerlCells);
  brdf::resample_grid(brdf::SampleTree(kept, o.local.mapping), kept, o.local, kd);
  const std::vector<double> err = weight_errors(parts[1], fitted, kd, b, c.ladder, out.epsilon);
  for (std::size_t l = 0; l < c.ladder.size(); ++l) out.rows.push_back({.weight = c.ladder[l], .error = err[l]});
  out.weight = c.ladder[least(err)];
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

nlohmann::ordered_json cap_weight_json(const CapWeightChoice& c) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const CapWeightRow& r : c.rows) rows.push_back({{"weight", r.weight}, {"error", r.error}});
  return {{"weight", c.weight},   {"held_samples", c.held_samples}, {"held_cells", c.held_cells},
          {"epsilon", c.epsilon}, {"seconds", c.seconds},           {"cap_rows", c.cap_rows},
          {"rows", rows}};
}

}  // namespace specula::acquire
