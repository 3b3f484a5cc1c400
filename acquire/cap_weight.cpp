#include "specula/acquire/cap_weight.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <memory>

#include "specula/acquire/peak_cap.h"
#include "specula/acquire/scan_holdout.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_mapping.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

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

// The kd-tree's estimate over `kept` at the centres of the cells of `at` (positions in valid_cells()) into kd
// (bands x kMerlCells, left as it is where it has no support), as resample_grid computes a cell; only the
// neighbours' values are read.
void kd_at(const brdf::SampleSource& kept, const brdf::ResampleOptions& local, std::span<const std::uint32_t> at,
           std::span<float> kd) {
  const auto tree = std::make_shared<const brdf::SampleTree>(kept, local.mapping);
  const auto& cells = valid_cells();
  const std::size_t b = kept.bands(), n = at.size();
  std::vector<brdf::IsoAngles> query(n);
  for (std::size_t i = 0; i < n; ++i)
    query[i] = brdf::iso_angles(brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(std::size_t(cells[at[i]])))));
  std::vector<brdf::Neighbours> nb(n);
  tree->nearest_each(query, local.k + 1, nb);  // k + 1 covers the reach of the weightings that have one
  std::vector<std::uint8_t> needed(kept.size(), 0);
  for (const brdf::Neighbours& x : nb)
    for (const std::uint32_t s : x.index) needed[s] = 1;
  nb = {};
  std::vector<float> values(kept.size() * b, 0.0f), block;
  const std::size_t rows = std::max<std::size_t>(1, kept.block_rows());
  for (std::size_t first = 0; first < kept.size(); first += rows) {
    const std::size_t count = std::min(rows, kept.size() - first);
    if (std::none_of(needed.begin() + std::ptrdiff_t(first), needed.begin() + std::ptrdiff_t(first + count),
                     [](std::uint8_t x) { return x != 0; }))
      continue;
    block.resize(count * b);
    kept.read_values(first, count, block);
    for (std::size_t s = 0; s < count; ++s)
      if (needed[first + s])
        std::copy_n(block.begin() + std::ptrdiff_t(s * b), b, values.begin() + std::ptrdiff_t((first + s) * b));
  }
  const brdf::Resampler r(tree, values, b, local);
  parallel_for(
      n,
      [&](std::size_t i) {
        thread_local std::vector<float> out;
        out.resize(b);
        if (!r.predict(query[i], out)) return;
        for (std::size_t k = 0; k < b; ++k) kd[k * brdf::kMerlCells + cells[at[i]]] = out[k];
      },
      64);
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
  std::vector<std::uint32_t> at;  // the rehearsal's cells (positions in cells), the only ones read of the fit
  std::vector<std::uint8_t> rehearsal(brdf::kMerlCells, 0);
  for (std::size_t v = 0; v < cells.size(); ++v)
    if (in_rehearsal(cap, cells[v])) {
      at.push_back(std::uint32_t(v));
      rehearsal[cells[v]] = 1;
    }
  Buffer<float> fitted(b * brdf::kMerlCells, -1.0f);
  fit_prior(prior, components, parts[0], o.fit, fitted, at);
  if (o.ceiling) bound_by_ceiling(prior, rehearsal, fitted);
  out.epsilon = judge_epsilon(parts[0], prior, b);
  const KeptSamples kept(src, held);
  Buffer<float> kd(b * brdf::kMerlCells, -1.0f);
  kd_at(kept, o.local, parts[1].cell, kd);
  const std::vector<double> err = weight_errors(parts[1], fitted, kd, b, c.ladder, out.epsilon, o.log_blend);
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
