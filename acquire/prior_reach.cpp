#include "specula/acquire/prior_reach.h"

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "specula/acquire/bandwidth.h"
#include "specula/acquire/base_resample.h"
#include "specula/acquire/retro_band.h"
#include "specula/acquire/retro_trend.h"
#include "specula/acquire/scan_holdout.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

void check_reach_options(const ReachOptions& o) {
  if (o.ladder.empty()) throw UsageError("confidence reach: the ladder of reaches is empty");
  for (std::size_t l = 0; l < o.ladder.size(); ++l)
    if (!(o.ladder[l] > 0 && o.ladder[l] <= 1) || (l > 0 && o.ladder[l] <= o.ladder[l - 1]))
      throw UsageError("confidence reach: the ladder must ascend strictly within (0, 1]");
  if (!(o.held_out > 0 && o.held_out < 1)) throw UsageError("confidence reach: held_out must be in (0, 1)");
  const auto& g = o.theta_h_groups;
  if (g.size() < 2 || g.front() != 0 || g.back() != brdf::kMerlThetaH || !std::is_sorted(g.begin(), g.end()) ||
      std::adjacent_find(g.begin(), g.end()) != g.end())
    throw UsageError("confidence reach: theta_h groups must ascend strictly from row 0 to row 90");
  for (std::size_t l = 0; l < o.k_ladder.size(); ++l)
    if (o.k_ladder[l] < 1 || o.k_ladder[l] > 100000 || (l > 0 && o.k_ladder[l] <= o.k_ladder[l - 1]))
      throw UsageError("confidence reach: the ladder of k must ascend strictly within [1, 100000]");
  for (std::size_t l = 0; l < o.retro_ladder.size(); ++l)
    if (!(o.retro_ladder[l] >= 0 && o.retro_ladder[l] <= 1) || (l > 0 && o.retro_ladder[l] <= o.retro_ladder[l - 1]))
      throw UsageError("confidence reach: the retro band's ladder of weights must ascend strictly within [0, 1]");
}

// Per held-out cell of obs and ladder entry, its error (cells x ladder, row-major).
std::vector<double> held_out_errors(const PriorObservations& obs, std::span<const float> fitted,
                                    std::span<const float> kd, std::span<const float> gaps, std::size_t b,
                                    const ReachOptions& r, double max_gap, double eps) {
  return blend_error_table(obs, fitted, kd, b, r.ladder.size(), eps, false, [&](std::size_t cell, std::size_t l) {
    return support_confidence(gaps[cell], max_gap, r.ladder[l]);
  });
}

// Per ladder entry the mean of err (cells x ladder) over the held-out cells o with keep(o), summed in their order;
// the count of such cells into n.
template <class Keep>
std::vector<double> mean_errors(const std::vector<double>& err, std::size_t m, const Keep& keep, std::size_t& n) {
  std::vector<double> mean(m, 0.0);
  n = 0;
  for (std::size_t o = 0; m && o < err.size() / m; ++o) {
    if (!keep(o)) continue;
    ++n;
    for (std::size_t l = 0; l < m; ++l) mean[l] += err[o * m + l];
  }
  for (double& x : mean) x = n ? x / double(n) : 0.0;
  return mean;
}

// Per ladder entry the mean of err (cells x ladder) over all its held-out cells.
std::vector<double> overall_means(const std::vector<double>& err, std::size_t m) {
  std::size_t n = 0;
  return mean_errors(
      err, m, [](std::size_t) { return true; }, n);
}

// The band's choice on one ladder's errors err (held band cells x ladder, group_of: each cell's theta_h group).
struct BandPick {
  std::vector<double> mean;  // per ladder entry, over all the held band cells
  std::size_t overall = 0;   // the ladder index of least mean
  std::vector<std::size_t> group, group_cells;
  std::vector<std::vector<double>> group_mean;
  double error = 0;  // the mean over the held band cells, each at its group's weight
};

BandPick pick_band(const std::vector<double>& err, std::size_t m, const std::vector<std::size_t>& group_of,
                   const ReachOptions& r) {
  BandPick p;
  const std::size_t n = m ? err.size() / m : 0;
  p.mean = overall_means(err, m);
  p.overall = least(p.mean);
  for (std::size_t q = 0; q + 1 < r.theta_h_groups.size(); ++q) {
    std::size_t cells = 0;
    p.group_mean.push_back(mean_errors(
        err, m, [&](std::size_t o) { return group_of[o] == q; }, cells));
    p.group_cells.push_back(cells);
    p.group.push_back(r.retro_by_group && cells >= r.min_group_cells ? least(p.group_mean.back()) : p.overall);
  }
  for (std::size_t o = 0; o < n; ++o) p.error += err[o * m + p.group[group_of[o]]];
  p.error = n ? p.error / double(n) : 0.0;
  return p;
}

std::vector<ReachRow> ladder_rows(std::span<const double> ladder, const std::vector<double>& mean) {
  std::vector<ReachRow> rows;
  for (std::size_t l = 0; l < mean.size(); ++l) rows.push_back({.reach = ladder[l], .error = mean[l]});
  return rows;
}

// The band's weights from its held cells `band` (the kd-tree's estimate kd, continued in place with out's
// retro_exponent when tried), into out (its groups already made).
void choose_band(const PriorObservations& band, std::span<const float> fitted, std::span<float> kd, std::size_t b,
                 bool log, const ReachOptions& r, ReachChoice& out) {
  const auto& cells = valid_cells();
  std::vector<std::size_t> group_of(band.cell.size(), 0);
  for (std::size_t o = 0; o < band.cell.size(); ++o) {
    const int row = brdf::merl_cell(std::size_t(cells[band.cell[o]])).theta_h;
    while (group_of[o] + 2 < r.theta_h_groups.size() && row >= r.theta_h_groups[group_of[o] + 1]) ++group_of[o];
  }
  const std::size_t m = r.retro_ladder.size();
  BandPick pick = pick_band(weight_error_table(band, fitted, kd, b, r.retro_ladder, out.epsilon, log), m, group_of, r);
  out.retro_rows = ladder_rows(r.retro_ladder, pick.mean);
  if (r.retro_continued) {
    continue_retro(kd, b, out.holdout.band_first, out.holdout.band_end - out.holdout.band_first, out.retro_exponent,
                   kd);
    BandPick cont =
        pick_band(weight_error_table(band, fitted, kd, b, r.retro_ladder, out.epsilon, log), m, group_of, r);
    out.retro_continued_rows = ladder_rows(r.retro_ladder, cont.mean);
    if (cont.error < pick.error) {
      out.retro_continued = true;
      pick = std::move(cont);
    }
  }
  out.retro_weight = r.retro_ladder[pick.overall];
  for (std::size_t q = 0; q < out.groups.size(); ++q) {
    out.groups[q].retro_cells = pick.group_cells[q];
    out.groups[q].retro_weight = r.retro_ladder[pick.group[q]];
    out.groups[q].retro_rows = ladder_rows(r.retro_ladder, pick.group_mean[q]);
  }
}

// Copies the theta_d rows [first, end) of grid (bands x kMerlCells) into rows, or back into grid when `back`.
void copy_theta_d_rows(std::span<float> grid, std::size_t b, int first, int end, std::vector<float>& rows, bool back) {
  rows.resize(b * std::size_t(brdf::kMerlThetaH) * std::size_t(end - first) * brdf::kMerlPhiD);
  std::size_t at = 0;
  for (std::size_t k = 0; k < b; ++k)
    for (int h = 0; h < brdf::kMerlThetaH; ++h)
      for (int d = first; d < end; ++d) {
        float* row = grid.data() + k * brdf::kMerlCells + brdf::merl_index({h, d, 0});
        if (back)
          std::copy_n(rows.data() + at, brdf::kMerlPhiD, row);
        else
          std::copy_n(row, brdf::kMerlPhiD, rows.data() + at);
        at += brdf::kMerlPhiD;
      }
}

// The blend resample_with_prior makes from the kept samples with the choices of c: the held band's rows at their
// group's weight of the chosen estimate kd (continued or not, as c says), the rows above at their group's reach, the
// fit alone below the band. The cap is blended as elsewhere and neither the ceiling nor the energy bound is applied:
// the rehearsal judges the band only.
Buffer<float> rehearsal_blend(std::span<const float> fitted, std::span<const float> kd, std::span<const float> gaps,
                              std::size_t b, const ReachChoice& c, double max_gap, bool log) {
  const std::vector<double> reach = reach_by_theta_h(c), weight = retro_weight_by_theta_h(c);
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  Buffer<float> out(fitted.begin(), fitted.end());
  parallel_for(
      cells.size(),
      [&](std::size_t i) {
        const std::size_t cell = cells[i];
        const brdf::MerlCell m = brdf::merl_cell(cell);
        if (m.theta_d < c.holdout.band_first || !(kd[cell] >= 0)) return;
        const bool band = m.theta_d < c.holdout.band_end;
        const double w = band ? weight[std::size_t(m.theta_h)]
                              : support_confidence(gaps[cell], max_gap, reach[std::size_t(m.theta_h)]);
        for (std::size_t k = 0; k < b; ++k) {
          const std::size_t at = k * brdf::kMerlCells + cell;
          out[at] = float(mix_estimates(kd[at], fitted[at], w, cosines[i], c.epsilon, band && log));
        }
      },
      4096);
  return out;
}

// The kd-tree's k: o.local.k, or of r.k_ladder the one whose least mean error over the reach ladder at the held-out
// cells is least (the smaller on a tie), each k's estimate made at those cells alone; each k's least error into
// out.k_rows.
std::size_t k_of_least_error(const brdf::SampleTree& tree, const KeptSamples& kept, const PriorObservations& held,
                             std::span<const float> fitted, const PriorResampleOptions& o, const ReachOptions& r,
                             ReachChoice& out) {
  if (r.k_ladder.empty()) return o.local.k;
  const std::size_t m = r.ladder.size();
  const auto& cells = valid_cells();
  std::vector<std::uint32_t> at;
  for (const std::uint32_t v : held.cell) at.push_back(cells[v]);
  std::sort(at.begin(), at.end());
  Buffer<float> kd(kept.bands() * brdf::kMerlCells, -1.0f);
  std::vector<float> gaps(brdf::kMerlCells, -1.0f);
  std::size_t best = 0;
  for (const std::size_t k : r.k_ladder) {
    brdf::ResampleOptions local = o.local;
    local.k = k;
    brdf::resample_cells(tree, kept, local, at, kd, gaps);
    const std::vector<double> mean =
        overall_means(held_out_errors(held, fitted, kd, gaps, kept.bands(), r, local.max_gap, out.epsilon), m);
    const double error = *std::min_element(mean.begin(), mean.end());
    out.k_rows.push_back({.reach = double(k), .error = error});
    if (error < out.k_rows[best].error) best = out.k_rows.size() - 1;
  }
  return r.k_ladder[best];
}

// The lowest theta_d row of the cells of obs (kMerlThetaD for none).
int lowest_row(const PriorObservations& obs) {
  int lowest = brdf::kMerlThetaD;
  for (const std::uint32_t v : obs.cell) lowest = std::min(lowest, brdf::merl_cell(valid_cells()[v]).theta_d);
  return lowest;
}

// The theta_d rows below which the carry's rehearsal reads the blend, made from the samples below
// carry_rehearsal_rows (their cells' corners reach one row further); 0 without a carry rehearsed.
int carry_blend_rows(const ReachHoldout& h, const ReachOptions& r, int lowest) {
  if (!r.retro_residuals || h.band_end <= h.band_first) return 0;
  return std::min(carry_rehearsal_rows(h.band_end, lowest, *r.retro_residuals) + 1, brdf::kMerlThetaD);
}

// The cells (positions in valid_cells(), ascending) where the rehearsal reads the fit and the kd-tree's estimate:
// the held-out cells `held`, and with a held band every valid cell of theta_d rows [band_first, end): the band, the
// rows its continuation reads (as many above it) and those below `carry_rows`.
std::vector<std::uint32_t> rehearsal_cells(const PriorObservations& held, const ReachHoldout& h, int carry_rows) {
  const auto& cells = valid_cells();
  const int end = h.band_end > h.band_first
                      ? std::min(std::max(2 * h.band_end - h.band_first, carry_rows), brdf::kMerlThetaD)
                      : h.band_first;
  std::vector<std::uint8_t> wanted(cells.size(), 0);
  for (const std::uint32_t v : held.cell) wanted[v] = 1;
  std::vector<std::uint32_t> at;
  for (std::size_t v = 0; v < cells.size(); ++v) {
    const int row = brdf::merl_cell(cells[v]).theta_d;
    if (wanted[v] || (row >= h.band_first && row < end)) at.push_back(std::uint32_t(v));
  }
  return at;
}

// The band's weights chosen at its held cells parts[2] and, when asked, the carry rehearsed on the blend those choices
// make (choose_retro_residuals) from the kept samples below carry_rehearsal_rows alone; fitted, kd and gaps hold the
// fit and the kd-tree's estimate where those read them. Their lowest row is that of the kept cell means parts[0]: the
// blend holds a value >= 0 at every valid cell of the rows they read (the fit's are), and a sample's own cell is one
// of its corners, so the correction takes every sample the cell means take.
void rehearse_band(const brdf::SampleSource& src, const std::vector<PriorObservations>& parts,
                   std::span<const float> fitted, std::span<float> kd, std::span<const float> gaps,
                   const PriorResampleOptions& o, const ReachOptions& r, ReachChoice& out) {
  const std::size_t b = src.bands();
  const int first = out.holdout.band_first, end = out.holdout.band_end;
  std::vector<float> plain_rows;  // the kd-tree's band rows, which trying the continuation overwrites
  if (r.retro_residuals && r.retro_continued) copy_theta_d_rows(kd, b, first, end, plain_rows, false);
  choose_band(parts[2], fitted, kd, b, o.log_blend, r, out);
  if (!r.retro_residuals) return;
  if (!plain_rows.empty() && !out.retro_continued) copy_theta_d_rows(kd, b, first, end, plain_rows, true);
  std::vector<float>().swap(plain_rows);
  const int rows = carry_rehearsal_rows(end, lowest_row(parts[0]), *r.retro_residuals);
  std::vector<std::uint8_t> far(out.holdout.held.size());
  for (std::size_t s = 0; s < far.size(); ++s) far[s] = out.holdout.held[s] != 0 || out.holdout.theta_d_row[s] >= rows;
  const Buffer<float> blend = rehearsal_blend(fitted, kd, gaps, b, out, o.local.max_gap, o.log_blend);
  out.retro_residuals = choose_retro_residuals(KeptSamples(src, far), parts[2], blend, *r.retro_residuals, out.epsilon);
}

}  // namespace

ReachHoldout reach_holdout(const brdf::SampleSource& src, const ReachOptions& o) {
  check_reach_options(o);
  ReachHoldout h;
  std::vector<std::uint8_t>& own_row = h.theta_d_row;
  own_row.resize(src.size());
  const std::vector<std::int32_t> slots = sample_slots(src, own_row);
  const auto& cells = valid_cells();
  std::vector<std::uint32_t> count(cells.size(), 0);
  for (const std::int32_t v : slots)
    if (v >= 0) ++count[std::size_t(v)];
  const auto row_of = [&](std::size_t v) { return brdf::merl_cell(std::size_t(cells[v])).theta_d; };
  std::vector<std::uint32_t> observed;
  int highest = -1;
  for (std::size_t i = 0; i < count.size(); ++i)
    if (count[i] > 0) {
      observed.push_back(std::uint32_t(i));
      highest = std::max(highest, row_of(i));
    }
  h.retro_rows = unseen_retro_rows(observed);  // the band the blend gives its weight to, by the blend's own rule
  if (!o.retro_ladder.empty() && h.retro_rows > 0 && h.retro_rows < brdf::kMerlThetaD &&
      highest >= std::min(2 * h.retro_rows, brdf::kMerlThetaD)) {  // some rows must stay to extrapolate from
    h.band_first = h.retro_rows;
    h.band_end = std::min(2 * h.retro_rows, brdf::kMerlThetaD);
  }
  const auto in_band = [&](std::size_t v) { return row_of(v) >= h.band_first && row_of(v) < h.band_end; };
  std::vector<std::uint32_t> splittable;
  for (std::size_t i = 0; i < count.size(); ++i) {
    h.observed_cells += count[i] > 0;
    if (count[i] >= 2 && !in_band(i)) splittable.push_back(std::uint32_t(i));
  }
  if (splittable.empty())
    throw InputError("confidence reach: no valid cell holds two samples, so none can lose half of them to validate on");
  const std::size_t want =
      std::clamp<std::size_t>(std::size_t(std::llround(o.held_out * double(splittable.size()))), 1, splittable.size());
  std::vector<std::uint8_t> chosen(count.size(), 0);
  for (const std::size_t j : select_indices(splittable.size(), want, o.seed)) chosen[splittable[j]] = 1;
  h.held_cells = want;
  h.held.assign(slots.size(), 0);
  std::vector<std::uint32_t> seen(count.size(), 0);
  for (std::size_t s = 0; s < slots.size(); ++s) {
    if (own_row[s] < h.band_end && (slots[s] < 0 || own_row[s] >= h.band_first)) {
      h.held[s] = 2;  // by its own row: a sample whose cell lies below the horizon would feed the kd-tree in the band
    } else if (slots[s] >= 0) {
      const std::size_t v = std::size_t(slots[s]);
      if (chosen[v] && seen[v]++ % 2 == 1) h.held[s] = 1;
    }
  }
  return h;
}

ReachChoice choose_confidence_reach(const brdf::SampleSource& src, const BrdfPrior& prior,
                                    const PriorResampleOptions& o, const ReachOptions& r) {
  return choose_confidence_reach(src, prior, memory_components(prior), o, r);
}

ReachChoice choose_confidence_reach(const brdf::SampleSource& src, const BrdfPrior& prior,
                                    const ComponentSource& components, const PriorResampleOptions& o,
                                    const ReachOptions& r) {
  check_reach_options(r);
  check_options(o.local);
  if (o.residuals) throw UsageError("confidence reach: chosen for the blend only, not the residuals form");
  if (src.bands() != prior.wavelengths.size())
    throw UsageError("prior: the samples have " + std::to_string(src.bands()) + " bands, the prior " +
                     std::to_string(prior.wavelengths.size()) + "; build the prior on the samples' bands");
  const auto t0 = std::chrono::steady_clock::now();
  ReachChoice out;
  out.holdout = reach_holdout(src, r);
  const std::vector<PriorObservations> parts =
      cell_means(src, o.fit.weights != PriorWeights::scatter, out.holdout.held, 3);
  const std::size_t b = src.bands();
  const std::vector<std::uint32_t> at =
      rehearsal_cells(parts[1], out.holdout, carry_blend_rows(out.holdout, r, lowest_row(parts[0])));
  Buffer<float> fitted(b * brdf::kMerlCells, -1.0f);
  fit_prior(prior, components, parts[0], o.fit, fitted, at);
  out.epsilon = judge_epsilon(parts[0], prior, b);
  const KeptSamples kept(src, out.holdout.held);
  const brdf::SampleTree tree(kept, o.local.mapping);
  brdf::ResampleOptions local = o.local;
  local.k = out.k = k_of_least_error(tree, kept, parts[1], fitted, o, r, out);
  Buffer<float> kd(b * brdf::kMerlCells, -1.0f);
  std::vector<float> gaps(brdf::kMerlCells, -1.0f);
  std::vector<std::uint32_t> at_cells(at.size());
  for (std::size_t t = 0; t < at.size(); ++t) at_cells[t] = valid_cells()[at[t]];
  brdf::resample_cells(tree, kept, local, at_cells, kd, gaps);
  const std::size_t m = r.ladder.size();
  const std::vector<double> err = held_out_errors(parts[1], fitted, kd, gaps, b, r, local.max_gap, out.epsilon);
  const std::vector<double> mean = overall_means(err, m);
  for (std::size_t l = 0; l < m; ++l) out.rows.push_back({.reach = r.ladder[l], .error = mean[l]});
  out.reach = r.ladder[least(mean)];
  const auto& cells = valid_cells();
  for (std::size_t q = 0; q + 1 < r.theta_h_groups.size(); ++q) {
    ReachGroup g{.first = r.theta_h_groups[q], .end = r.theta_h_groups[q + 1]};
    const std::vector<double> gm = mean_errors(
        err, m,
        [&](std::size_t o) {
          const int row = brdf::merl_cell(std::size_t(cells[parts[1].cell[o]])).theta_h;
          return row >= g.first && row < g.end;
        },
        g.cells);
    for (std::size_t l = 0; l < m; ++l) g.rows.push_back({.reach = r.ladder[l], .error = gm[l]});
    g.reach = g.cells >= r.min_group_cells ? r.ladder[least(gm)] : out.reach;
    out.groups.push_back(std::move(g));
  }
  out.retro_exponent = retro_exponent(prior.retro_exponents, out.holdout.retro_rows);
  if (!parts[2].cell.empty()) rehearse_band(src, parts, fitted, kd, gaps, o, r, out);
  out.holdout.held = {};
  out.holdout.theta_d_row = {};
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

nlohmann::ordered_json reach_choice_json(const ReachChoice& c, const ReachOptions& r) {
  const auto rows_json = [](const std::vector<ReachRow>& rows, const char* key) {
    nlohmann::ordered_json out = nlohmann::ordered_json::array();
    for (const ReachRow& row : rows) out.push_back({{key, row.reach}, {"error", row.error}});
    return out;
  };
  nlohmann::ordered_json j = {{"reach", c.reach},
                              {"held_out", r.held_out},
                              {"seed", r.seed},
                              {"epsilon", c.epsilon},
                              {"observed_cells", c.holdout.observed_cells},
                              {"held_cells", c.holdout.held_cells},
                              {"seconds", c.seconds},
                              {"rows", rows_json(c.rows, "reach")}};
  if (!c.k_rows.empty()) {
    j["k"] = c.k;
    j["k_rows"] = rows_json(c.k_rows, "k");
  }
  nlohmann::ordered_json groups = nlohmann::ordered_json::array();
  for (const ReachGroup& g : c.groups)
    groups.push_back(
        {{"theta_h_rows", {g.first, g.end}},
         {"held_cells", g.cells},
         {"reach", g.reach},
         {"rows", rows_json(g.rows, "reach")},
         {"retro_cells", g.retro_cells},
         {"retro_weight", g.retro_weight ? nlohmann::ordered_json(*g.retro_weight) : nlohmann::ordered_json()},
         {"retro_rows", rows_json(g.retro_rows, "weight")}});
  j["theta_h_groups"] = groups;
  j["retro_band"] = {
      {"unseen_rows", c.holdout.retro_rows},
      {"held_rows", {c.holdout.band_first, c.holdout.band_end}},
      {"weight", c.retro_weight ? nlohmann::ordered_json(*c.retro_weight) : nlohmann::ordered_json()},
      {"rows", rows_json(c.retro_rows, "weight")},
      {"continued", c.retro_continued},
      {"continued_rows", rows_json(c.retro_continued_rows, "weight")},
      {"exponent", c.retro_exponent},
      {"residual_carry", c.retro_residuals ? retro_residual_json(*c.retro_residuals) : nlohmann::ordered_json()}};
  return j;
}

std::vector<double> reach_by_theta_h(const ReachChoice& c) {
  std::vector<double> out(std::size_t(brdf::kMerlThetaH), c.reach);
  for (const ReachGroup& g : c.groups)
    for (int row = g.first; row < g.end; ++row) out[std::size_t(row)] = g.reach;
  return out;
}

std::vector<double> retro_weight_by_theta_h(const ReachChoice& c) {
  if (!c.retro_weight) return {};
  std::vector<double> out(std::size_t(brdf::kMerlThetaH), *c.retro_weight);
  for (const ReachGroup& g : c.groups)
    for (int row = g.first; row < g.end; ++row) out[std::size_t(row)] = g.retro_weight.value_or(*c.retro_weight);
  return out;
}

std::string reach_provenance(const ReachChoice& c, const ReachOptions& r) {
  std::string groups, band;
  for (const ReachGroup& g : c.groups) {
    groups += fmt::format("{}{}-{}:{}", groups.empty() ? "" : ",", g.first, g.end, g.reach);
    if (c.retro_weight)
      band +=
          fmt::format("{}{}-{}:{}", band.empty() ? "" : ",", g.first, g.end, g.retro_weight.value_or(*c.retro_weight));
  }
  std::string ks;
  for (const ReachRow& row : c.k_rows) ks += fmt::format("{}{}", ks.empty() ? " k_by_holdout=" : ",", row.reach);
  return fmt::format(
      "confidence_reach={} reach_by_theta_h={} reach_auto=holdout held_out={} seed={}{}{}", c.reach, groups, r.held_out,
      r.seed, ks,
      c.retro_weight
          ? fmt::format(" retro_weight={} retro_by_theta_h={} retro_rows={}{}{}", *c.retro_weight, band,
                        c.holdout.retro_rows,
                        c.retro_continued ? fmt::format(" retro=continued retro_exponent={}", c.retro_exponent) : "",
                        !c.retro_residuals           ? ""
                        : c.retro_residuals->carried ? " retro_residuals=carried"
                                                     : " retro_residuals=plain")
          : std::string());
}

}  // namespace specula::acquire
