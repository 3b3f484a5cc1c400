// The kd-tree's reach in the prior's blend chosen by holdout (acquire/prior_reach.h): a material the prior cannot
// represent, sampled densely without noise, gets a large reach (the kd-tree is right); a material of the prior's
// family under heavy noise gets a small one (the fit is right); and the validation errors equal a brute-force
// recomputation from the held-out cells, a separately built fit and kd-tree estimate, on any thread count. The
// kd-tree's k chosen with the reach is each k's own choice at its best, and noisy samples take the larger k.
#include "specula/acquire/prior_reach.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "ward_family.h"

using namespace specula;

namespace {

const WavelengthGrid& kBands = test::kWardBands;
using test::ward;

const double kFamily[][4] = {
    {0.6, 0.1, 0.05, 0.05}, {0.2, 0.5, 0.1, 0.1}, {0.4, 0.4, 0.02, 0.2}, {0.1, 0.1, 0.2, 0.07}, {0.7, 0.3, 0.08, 0.15}};

// A retro-reflective bump 1 + 2 exp(-(theta_d / 10 degrees)^2) on a Ward material, as a fabric has.
double bump(double theta_d) { return 1 + 2 * std::exp(-std::pow(theta_d / (10 * std::numbers::pi / 180), 2)); }

// A prior of the five Ward materials of kFamily, each times the bump when bumped.
acquire::BrdfPrior build_family(bool bumped) {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < std::size(kFamily); ++i) names.push_back("m" + std::to_string(i));
  return acquire::build_prior(std::size(kFamily),
                              [bumped](std::size_t i) {
                                store::Grid g;
                                g.wavelengths = kBands;
                                g.brdf.resize(kBands.size() * brdf::kMerlCells);
                                brdf::evaluate_grid(ward(kFamily[i][0], kFamily[i][1], kFamily[i][2], kFamily[i][3]),
                                                    g.brdf);
                                for (std::size_t c = 0; bumped && c < brdf::kMerlCells; ++c) {
                                  const double f = bump(brdf::merl_cell_centre(brdf::merl_cell(c)).theta_d);
                                  for (std::size_t k = 0; k < 5; ++k) g.brdf[k * brdf::kMerlCells + c] *= float(f);
                                }
                                return g;
                              },
                              names, {.channels = 3});
}

// The two priors, built once for the file.
const acquire::BrdfPrior& family_prior() {
  static const acquire::BrdfPrior p = build_family(false);
  return p;
}
const acquire::BrdfPrior& bumped_prior() {
  static const acquire::BrdfPrior p = build_family(true);
  return p;
}

// n samples of m with both directions within 40 degrees of the normal, each value times (1 + noise N(0, 1)) clamped
// at 0 and times ripple(theta_i, theta_o).
struct Scan {
  std::vector<double> angles;
  std::vector<float> values;
};
Scan scan_of(const brdf::SpectralModel& m, std::size_t n, double noise, double ripple, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> z(0, 1);
  Scan s;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = std::acos(1 - u(rng) * (1 - std::cos(0.7))), to = std::acos(1 - u(rng) * (1 - std::cos(0.7)));
    s.angles.insert(s.angles.end(), {ti, 0.0, to, (2 * u(rng) - 1) * std::numbers::pi});
  }
  s.values.resize(n * 5);
  brdf::evaluate_at(m, s.angles, s.values);
  for (std::size_t i = 0; i < n; ++i) {
    const double f = 1 + ripple * std::sin(12 * s.angles[4 * i]) * std::cos(9 * s.angles[4 * i + 2]);
    for (std::size_t k = 0; k < 5; ++k)
      s.values[i * 5 + k] = float(std::max(0.0, s.values[i * 5 + k] * f * (1 + noise * z(rng))));
  }
  return s;
}

// The judge's eps written out: the prior's times min(1, the upper median over the observed cells of the band-mean
// cos-weighted cell mean over the upper median of the prior's reference at the same cells).
double judge_eps(const acquire::PriorObservations& obs, const acquire::BrdfPrior& prior) {
  std::vector<double> v, ref;
  for (std::size_t o = 0; o < obs.cell.size(); ++o) {
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(std::size_t(acquire::valid_cells()[obs.cell[o]]))), wi, wo);
    double mean = 0;
    for (std::size_t k = 0; k < 5; ++k) mean += obs.values[o * 5 + k] / 5.0;
    v.push_back(mean * wi.z() * wo.z());
    ref.push_back(prior.reference[obs.cell[o]]);
  }
  std::sort(v.begin(), v.end());
  std::sort(ref.begin(), ref.end());
  return prior.epsilon * std::min(1.0, v[v.size() / 2] / ref[ref.size() / 2]);
}

}  // namespace

TEST(PriorReach, ALargeReachWhereThePriorCannotFollowTheMaterialAndTheSamplesAreClean) {
  // A ripple no Ward of the family has: the fit smooths it, the kd-tree estimate of dense clean samples follows it.
  const Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 120000, 0.0, 0.6, 1);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), {}, {});
  EXPECT_GE(c.reach, 0.3);
  EXPECT_LT(c.rows.back().error, 0.5 * c.rows.front().error) << "the kd-tree clearly better than the prior alone";
}

TEST(PriorReach, ADarkMaterialIsJudgedAtItsOwnScale) {
  // The rippled material of the test above at a thousandth of its value: its whole body lies below the prior's eps
  // (1e-3 1/sr), where an error in the fit's domain hardly registers; judged with eps scaled to the material, the
  // kd-tree that follows the ripple is still chosen.
  Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 120000, 0.0, 0.6, 1);
  for (float& v : s.values) v *= 1e-3f;
  const brdf::MemorySamples src(s.angles, s.values, 5);
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), {}, {});
  EXPECT_LT(c.epsilon, 2e-3 * family_prior().epsilon);
  EXPECT_GE(c.reach, 0.3);
  EXPECT_LT(c.rows.back().error, 0.5 * c.rows.front().error);
}

// A Ward material times factor(half and difference angles), scanned everywhere but theta_d < 5 degrees (the rig's
// unseen band).
template <class Factor>
Scan band_scan_hd(const Factor& factor) {
  const Scan all = scan_of(ward(0.45, 0.25, 0.07, 0.12), 150000, 0.02, 0.0, 4);
  Scan s;
  for (std::size_t i = 0; i < all.angles.size() / 4; ++i) {
    const brdf::StdAngles a{all.angles[4 * i], all.angles[4 * i + 1], all.angles[4 * i + 2], all.angles[4 * i + 3]};
    const brdf::HalfDiff hd = brdf::half_diff(a);
    if (hd.theta_d < 5 * std::numbers::pi / 180) continue;
    s.angles.insert(s.angles.end(), &all.angles[4 * i], &all.angles[4 * i + 4]);
    for (std::size_t k = 0; k < 5; ++k) s.values.push_back(float(all.values[i * 5 + k] * factor(hd)));
  }
  return s;
}

// band_scan_hd of a factor of theta_d alone.
template <class Factor>
Scan band_scan(const Factor& factor) {
  return band_scan_hd([&](const brdf::HalfDiff& hd) { return factor(hd.theta_d); });
}

Scan band_scan(bool bumped) {
  return band_scan([&](double td) { return bumped ? bump(td) : 1.0; });
}

TEST(PriorReach, TheRetroBandsWeightIsChosenByTheBandOneHigher) {
  // Every member of the prior has the bump. A material with it: the prior continues the bump into the band, the
  // kd-tree flattens it, so the prior gets the weight. A material without it: the prior still adds the bump it always
  // saw, the kd-tree's continuation of the flat samples is right.
  const Scan with = band_scan(true), without = band_scan(false);
  const brdf::MemorySamples with_src(with.angles, with.values, 5), without_src(without.angles, without.values, 5);
  const acquire::ReachHoldout h = acquire::reach_holdout(with_src, {});
  EXPECT_EQ(h.retro_rows, 5);
  EXPECT_EQ(h.band_first, 5);
  EXPECT_EQ(h.band_end, 10);
  std::size_t in_band = 0;
  for (std::size_t i = 0; i < with.angles.size() / 4; ++i) {
    const brdf::StdAngles a{with.angles[4 * i], with.angles[4 * i + 1], with.angles[4 * i + 2], with.angles[4 * i + 3]};
    const int row = brdf::merl_cell(a).theta_d;
    const bool band = row >= 5 && row < 10;
    in_band += band;
    ASSERT_EQ(h.held[i] == 2, band) << "sample " << i << " in theta_d row " << row;
  }
  EXPECT_GT(in_band, 1000u);
  acquire::ReachOptions kd_only;  // the kd-tree's own estimate against the prior (the continuation: next test)
  kd_only.retro_continued = false;
  const acquire::ReachChoice cw = acquire::choose_confidence_reach(with_src, bumped_prior(), {}, kd_only);
  const acquire::ReachChoice cn = acquire::choose_confidence_reach(without_src, bumped_prior(), {}, kd_only);
  EXPECT_FALSE(cw.retro_continued || cn.retro_continued);
  EXPECT_TRUE(cw.retro_continued_rows.empty());
  ASSERT_TRUE(cw.retro_weight && cn.retro_weight);
  EXPECT_LE(*cw.retro_weight, 0.25);
  EXPECT_GE(*cn.retro_weight, 0.75);
  EXPECT_LT(cw.retro_rows.front().error, cw.retro_rows.back().error);
  EXPECT_GT(cn.retro_rows.front().error, cn.retro_rows.back().error);

  // No band held without a retro ladder.
  acquire::ReachOptions plain;
  plain.retro_ladder.clear();
  const acquire::ReachChoice cp = acquire::choose_confidence_reach(with_src, bumped_prior(), {}, plain);
  EXPECT_FALSE(cp.retro_weight);
  EXPECT_EQ(cp.holdout.band_end, cp.holdout.band_first);
}

TEST(PriorReach, SamplesOfCellsBelowTheHorizonAreHeldOutByTheirOwnRow) {
  // A sample may lie above the horizon while the centre of its MERL cell does not, so its cell gives it no slot; at
  // the held band's rows or below them it must still leave the kd-tree, as the band's other samples do. Planted near
  // grazing at 100 times the material's value, every such sample is held out and the choice is the one made without
  // them, bit for bit.
  const Scan base = band_scan(true);
  Scan s = base;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  const double deg = std::numbers::pi / 180;
  std::size_t planted = 0, below_band = 0;
  std::vector<std::size_t> rows;  // each planted sample's theta_d row, written out here
  while (planted < 3000) {
    const brdf::HalfDiff hd{.theta_h = (70 + 20 * u(rng)) * deg,
                            .phi_h = 0,
                            .theta_d = 10 * u(rng) * deg,
                            .phi_d = 2 * std::numbers::pi * u(rng)};
    Eigen::Vector3d wi, wo;
    brdf::directions(hd, wi, wo);
    const brdf::StdAngles a = brdf::std_angles(hd);
    const brdf::MerlCell cell = brdf::merl_cell(a);
    if (!(wi.z() > 0 && wo.z() > 0) || brdf::merl_cell_valid(cell)) continue;  // above the horizon, its cell not
    s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    for (std::size_t k = 0; k < 5; ++k) s.values.push_back(100.0f * s.values[k]);
    rows.push_back(std::size_t(cell.theta_d));
    below_band += cell.theta_d < 5;
    ++planted;
  }
  EXPECT_GT(below_band, 500u);
  const brdf::MemorySamples src(s.angles, s.values, 5), base_src(base.angles, base.values, 5);
  const acquire::ReachHoldout h = acquire::reach_holdout(src, {});
  ASSERT_EQ(h.band_end, 10);
  const std::size_t first = base.angles.size() / 4;
  for (std::size_t i = 0; i < planted; ++i)
    ASSERT_EQ(h.held[first + i], 2) << "planted sample " << i << " in theta_d row " << rows[i];
  acquire::ReachOptions r;
  r.retro_residuals = acquire::LogResidualOptions{};
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, bumped_prior(), {}, r);
  const acquire::ReachChoice want = acquire::choose_confidence_reach(base_src, bumped_prior(), {}, r);
  EXPECT_EQ(c.reach, want.reach);
  ASSERT_EQ(c.retro_rows.size(), want.retro_rows.size());
  for (std::size_t l = 0; l < c.retro_rows.size(); ++l) EXPECT_EQ(c.retro_rows[l].error, want.retro_rows[l].error);
  ASSERT_TRUE(c.retro_residuals && want.retro_residuals);
  EXPECT_EQ(c.retro_residuals->error_carried, want.retro_residuals->error_carried);
  EXPECT_EQ(c.retro_residuals->error_plain, want.retro_residuals->error_plain);
}

TEST(PriorReach, EachThetaHGroupTakesItsOwnWeightInTheBand) {
  // The retro bump the prior always has, but only where theta_h >= 22.5 degrees (rows 45-89, the last group): there the
  // prior is right, below it the kd-tree's flat estimate; by group each takes its side, as one weight neither can.
  const Scan s = band_scan_hd(
      [](const brdf::HalfDiff& hd) { return hd.theta_h >= std::numbers::pi / 8 ? bump(hd.theta_d) : 1.0; });
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::ReachOptions r;
  r.retro_continued = false;
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, bumped_prior(), {}, r);
  ASSERT_TRUE(c.retro_weight);
  ASSERT_EQ(c.groups.size(), 5u);
  const acquire::ReachGroup &mid = c.groups[3], &top = c.groups[4];
  ASSERT_GE(mid.retro_cells, r.min_group_cells);
  ASSERT_GE(top.retro_cells, r.min_group_cells);
  EXPECT_GE(*mid.retro_weight, 0.75);
  EXPECT_LE(*top.retro_weight, 0.25);
  EXPECT_LT(mid.retro_rows.back().error, mid.retro_rows.front().error);
  EXPECT_GT(top.retro_rows.back().error, top.retro_rows.front().error);
  r.retro_by_group = false;
  const acquire::ReachChoice one = acquire::choose_confidence_reach(src, bumped_prior(), {}, r);
  for (const acquire::ReachGroup& g : one.groups) EXPECT_EQ(g.retro_weight, one.retro_weight);

  // The result's band takes each row's group weight as its confidence where the kd-tree has support (away from the
  // cap round the peak, which keeps its own).
  acquire::PriorResampleOptions o{.local = {.k = 8}, .confidence_reach = 0.1};
  o.retro_weight = *c.retro_weight;
  o.retro_weight_by_theta_h = acquire::retro_weight_by_theta_h(c);
  std::vector<float> grid(5 * brdf::kMerlCells), conf(brdf::kMerlCells);
  acquire::resample_with_prior(src, bumped_prior(), o, grid, conf);
  std::size_t checked = 0;
  for (const std::uint32_t cell : acquire::valid_cells()) {
    const brdf::MerlCell m = brdf::merl_cell(std::size_t(cell));
    if (m.theta_d >= 5 || m.theta_h < mid.first || conf[cell] == 0) continue;
    const acquire::ReachGroup& g = m.theta_h >= top.first ? top : mid;
    ASSERT_FLOAT_EQ(conf[cell], float(*g.retro_weight)) << "theta_h row " << m.theta_h;
    ++checked;
  }
  EXPECT_GT(checked, 1000u);
  o.retro_weight_by_theta_h.assign(89, 0.5);
  EXPECT_THROW(acquire::resample_with_prior(src, bumped_prior(), o, grid, conf), UsageError);
}

TEST(PriorReach, AMaterialsOwnTrendInThetaDIsContinuedIntoTheBand) {
  // The material brightens as theta_d falls (exp(-30 theta_d^2), 24 % from 5 degrees to 0, even in theta_d as
  // reciprocity makes it), which no member of the prior does and the kd-tree's flat continuation misses: the continued
  // estimate is chosen, with a large weight, and in the result the band is far closer to the truth than without it.
  const auto trend = [](double td) { return std::exp(-30 * td * td); };
  const Scan s = band_scan(trend);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), {}, {});
  ASSERT_TRUE(c.retro_weight);
  EXPECT_TRUE(c.retro_continued);
  EXPECT_GE(*c.retro_weight, 0.75);
  ASSERT_EQ(c.retro_continued_rows.size(), c.retro_rows.size());
  EXPECT_LT(c.retro_continued_rows.back().error, 0.5 * c.retro_rows.back().error);

  acquire::PriorResampleOptions o{.local = {.k = 8}, .confidence_reach = 0.1};
  o.retro_weight = *c.retro_weight;
  std::vector<float> flat(5 * brdf::kMerlCells), cont(flat.size()), conf(brdf::kMerlCells);
  acquire::resample_with_prior(src, family_prior(), o, flat, conf);
  o.retro_continued = true;
  acquire::resample_with_prior(src, family_prior(), o, cont, conf);
  const brdf::Ward truth = ward(0.45, 0.25, 0.07, 0.12);
  std::vector<double> at_centre(5);
  double err_flat = 0, err_cont = 0;
  std::size_t n = 0;
  for (const std::uint32_t cell : acquire::valid_cells()) {
    const brdf::MerlCell m = brdf::merl_cell(std::size_t(cell));
    if (m.theta_d >= 5 || m.theta_h < 5) continue;  // the band, away from the cap round the peak
    const brdf::HalfDiff hd = brdf::merl_cell_centre(m);
    const brdf::StdAngles a = brdf::std_angles(hd);
    if (a.theta_i > 0.6 || a.theta_o > 0.6) continue;  // where the scan (both directions within 0.7 rad) has samples
    truth.eval(a, at_centre);
    for (std::size_t k = 0; k < 5; ++k) {
      const double want = at_centre[k] * trend(hd.theta_d);
      err_flat += std::pow(std::log(flat[k * brdf::kMerlCells + cell] / want), 2);
      err_cont += std::pow(std::log(cont[k * brdf::kMerlCells + cell] / want), 2);
    }
    ++n;
  }
  ASSERT_GT(n, 2000u);
  EXPECT_LT(err_cont, 0.5 * err_flat) << "mean squared log error " << err_cont / n << " against " << err_flat / n;
}

TEST(PriorReach, EachThetaHRowTakesItsOwnReach) {
  const Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 40000, 0.02, 0.3, 5);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::PriorResampleOptions near{.local = {.k = 8}, .confidence_reach = 0.01}, far = near, mixed = near;
  far.confidence_reach = 1;
  mixed.reach_by_theta_h.assign(90, 1.0);
  std::fill_n(mixed.reach_by_theta_h.begin(), 30, 0.01);
  std::vector<float> gn(5 * brdf::kMerlCells), gf(gn.size()), gm(gn.size()), cn(brdf::kMerlCells), cf(brdf::kMerlCells),
      cm(brdf::kMerlCells);
  acquire::resample_with_prior(src, family_prior(), near, gn, cn);
  acquire::resample_with_prior(src, family_prior(), far, gf, cf);
  acquire::resample_with_prior(src, family_prior(), mixed, gm, cm);
  std::size_t differ = 0;
  for (const std::uint32_t c : acquire::valid_cells()) {
    const bool low = brdf::merl_cell(std::size_t(c)).theta_h < 30;
    const auto& want = low ? gn : gf;
    ASSERT_EQ(cm[c], (low ? cn : cf)[c]) << c;
    for (std::size_t k = 0; k < 5; ++k) ASSERT_EQ(gm[k * brdf::kMerlCells + c], want[k * brdf::kMerlCells + c]) << c;
    differ += cn[c] != cf[c];
  }
  EXPECT_GT(differ, 1000u) << "the two reaches must differ somewhere for the test to mean anything";
  mixed.reach_by_theta_h.resize(89);
  EXPECT_THROW(acquire::resample_with_prior(src, family_prior(), mixed, gm, cm), specula::UsageError);
}

TEST(PriorReach, ASmallReachWhereThePriorHoldsTheMaterialAndTheSamplesAreNoisy) {
  // A training material under 30 % noise, a kd-tree of 4 neighbours: the fit over all cells averages the noise away.
  const Scan s = scan_of(ward(kFamily[2][0], kFamily[2][1], kFamily[2][2], kFamily[2][3]), 120000, 0.3, 0.0, 2);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::PriorResampleOptions o;
  o.local.k = 4;
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), o, {});
  EXPECT_LE(c.reach, 0.03);
  // The held-out means of a sample or two carry the noise too (the same error under every reach).
  EXPECT_GT(c.rows.back().error, 1.15 * c.rows.front().error) << "the prior alone better than the kd-tree";
}

TEST(PriorReach, TheKdTreesKIsTheOneWhoseBlendTheHoldoutFindsClosest) {
  // Each k of the ladder judged alone (its own choice, o.local.k = k) gives the least error the ladder reports for
  // it, the k kept is the least of them, and everything else is that k's own choice.
  const Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 30000, 0.05, 0.3, 3);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::ReachOptions r{.k_ladder = {4, 48}};
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), {}, r);
  ASSERT_EQ(c.k_rows.size(), 2u);
  EXPECT_NE(c.k_rows[0].error, c.k_rows[1].error) << "the two k must differ for the test to mean anything";
  std::vector<acquire::ReachChoice> alone;
  for (const std::size_t k : r.k_ladder) {
    acquire::PriorResampleOptions o;
    o.local.k = k;
    alone.push_back(acquire::choose_confidence_reach(src, family_prior(), o, {}));
    EXPECT_TRUE(alone.back().k_rows.empty());
    EXPECT_EQ(alone.back().k, k);
  }
  std::size_t best = 0;
  for (std::size_t i = 0; i < alone.size(); ++i) {
    double least = INFINITY;
    for (const auto& row : alone[i].rows) least = std::min(least, row.error);
    EXPECT_EQ(c.k_rows[i].reach, double(r.k_ladder[i]));
    EXPECT_DOUBLE_EQ(c.k_rows[i].error, least) << r.k_ladder[i];
    if (c.k_rows[i].error < c.k_rows[best].error) best = i;
  }
  EXPECT_EQ(c.k, r.k_ladder[best]);
  const acquire::ReachChoice& same = alone[best];
  EXPECT_EQ(c.reach, same.reach);
  ASSERT_EQ(c.rows.size(), same.rows.size());
  for (std::size_t l = 0; l < c.rows.size(); ++l) EXPECT_DOUBLE_EQ(c.rows[l].error, same.rows[l].error);
  ASSERT_EQ(c.groups.size(), same.groups.size());
  for (std::size_t g = 0; g < c.groups.size(); ++g) EXPECT_EQ(c.groups[g].reach, same.groups[g].reach);
  r.k_ladder = {16, 4};
  EXPECT_THROW(acquire::choose_confidence_reach(src, family_prior(), {}, r), specula::UsageError);
}

TEST(PriorReach, NoisySamplesOfAMaterialThePriorCannotFollowTakeTheLargerK) {
  // The rippled material under 30 % noise: the kd-tree must carry the ripple, and more neighbours average its noise.
  const Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 120000, 0.3, 0.6, 4);
  const acquire::ReachChoice c = acquire::choose_confidence_reach(brdf::MemorySamples(s.angles, s.values, 5),
                                                                  family_prior(), {}, {.k_ladder = {2, 64}});
  EXPECT_EQ(c.k, 64u);
  EXPECT_LT(c.k_rows[1].error, 0.8 * c.k_rows[0].error) << c.k_rows[0].error << " " << c.k_rows[1].error;
}

TEST(PriorReach, ValidationErrorsEqualABruteForceRecomputation) {
  const Scan s = scan_of(ward(0.45, 0.25, 0.07, 0.12), 60000, 0.05, 0.3, 3);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::PriorResampleOptions o;
  o.local.k = 8;
  o.fit.weights = acquire::PriorWeights::count;
  const acquire::ReachOptions r;
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), o, r);
  const acquire::ReachHoldout h = acquire::reach_holdout(src, r);
  const std::size_t n = s.angles.size() / 4;
  ASSERT_EQ(h.held.size(), n);

  // Each sample's MERL cell, by the test's own lookup; per cell the kept and held-out samples' sums.
  struct Cell {
    std::size_t kept = 0, held = 0;
    std::vector<double> kept_sum = std::vector<double>(5, 0.0), held_sum = std::vector<double>(5, 0.0);
  };
  std::map<std::size_t, Cell> cells;
  std::vector<double> kept_angles;
  std::vector<float> kept_values;
  for (std::size_t i = 0; i < n; ++i) {
    const brdf::StdAngles a{s.angles[4 * i], s.angles[4 * i + 1], s.angles[4 * i + 2], s.angles[4 * i + 3]};
    Cell& cell = cells[brdf::merl_index(brdf::merl_cell(a))];
    const bool kept = !h.held[i];
    ++(kept ? cell.kept : cell.held);
    for (std::size_t k = 0; k < 5; ++k) (kept ? cell.kept_sum : cell.held_sum)[k] += s.values[i * 5 + k];
    if (kept) {
      kept_angles.insert(kept_angles.end(), &s.angles[4 * i], &s.angles[4 * i + 4]);
      kept_values.insert(kept_values.end(), &s.values[i * 5], &s.values[i * 5 + 5]);
    }
  }
  std::size_t splittable = 0, held_cells = 0;
  const auto& valid = acquire::valid_cells();
  acquire::PriorObservations kept_obs;
  for (const auto& [index, cell] : cells) {
    splittable += cell.kept + cell.held >= 2;
    held_cells += cell.held > 0;
    if (cell.held) {
      ASSERT_EQ(cell.held, (cell.kept + cell.held) / 2) << "every other sample of " << index;
    }
    kept_obs.cell.push_back(std::uint32_t(std::lower_bound(valid.begin(), valid.end(), index) - valid.begin()));
    for (std::size_t k = 0; k < 5; ++k) kept_obs.values.push_back(float(cell.kept_sum[k] / double(cell.kept)));
    kept_obs.weight.push_back(float(cell.kept));
  }
  EXPECT_EQ(h.observed_cells, cells.size());
  EXPECT_EQ(h.held_cells, held_cells);
  EXPECT_EQ(held_cells, std::size_t(std::llround(0.1 * double(splittable))));
  EXPECT_GT(held_cells, 100u);
  std::vector<float> fitted(5 * brdf::kMerlCells, -1.0f);
  acquire::fit_prior(family_prior(), kept_obs, o.fit, fitted);
  const brdf::Resampler kd(kept_angles, kept_values, 5, o.local);

  // At each held-out cell, for every reach, the log-domain error of the blend against the held-out samples' mean.
  const std::size_t m = r.ladder.size();
  std::vector<double> error(m, 0.0);
  // and per group of theta_h rows, by the test's own grouping of the default boundaries
  const int bounds[] = {0, 10, 20, 30, 45, 90};
  std::vector<std::vector<double>> group_error(5, std::vector<double>(m, 0.0));
  std::vector<std::size_t> group_cells(5, 0);
  const double eps = judge_eps(kept_obs, family_prior());
  EXPECT_NEAR(c.epsilon, eps, 1e-5 * eps);
  for (const auto& [index, cell] : cells) {
    if (!cell.held) continue;
    const brdf::StdAngles centre = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(index)));
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(index)), wi, wo);
    const double cc = wi.z() * wo.z();
    std::vector<float> local(5);
    const bool supported = kd.predict(centre, local);
    std::size_t q = 0;
    while (brdf::merl_cell(index).theta_h >= bounds[q + 1]) ++q;
    ++group_cells[q];
    brdf::Neighbours nb;
    kd.neighbours(centre, nb);
    for (std::size_t l = 0; l < m; ++l) {
      const double g = nb.gap / (r.ladder[l] * o.local.max_gap);
      const double conf = supported ? std::max(0.0, 1 - g * g) : 0.0;
      for (std::size_t k = 0; k < 5; ++k) {
        const double blend = conf * local[k] + (1 - conf) * fitted[k * brdf::kMerlCells + index];
        const double target = cell.held_sum[k] / double(cell.held);
        const double d = std::log((blend * cc + eps) / (target * cc + eps));
        error[l] += d * d / 5 / double(held_cells);
        group_error[q][l] += d * d / 5;
      }
    }
  }
  ASSERT_EQ(c.rows.size(), m);
  std::size_t best = 0;
  for (std::size_t l = 0; l < m; ++l) {
    EXPECT_NEAR(c.rows[l].error, error[l], 1e-4 * error[l]) << r.ladder[l];
    if (c.rows[l].error < c.rows[best].error) best = l;
  }
  EXPECT_EQ(c.reach, r.ladder[best]);
  EXPECT_GT(c.rows.front().error, 0.0);
  ASSERT_EQ(c.groups.size(), 5u);
  const std::vector<double> per_row = acquire::reach_by_theta_h(c);
  for (std::size_t q = 0; q < 5; ++q) {
    const acquire::ReachGroup& g = c.groups[q];
    EXPECT_EQ(g.first, bounds[q]);
    EXPECT_EQ(g.cells, group_cells[q]) << "group " << q;
    std::size_t gbest = 0;
    for (std::size_t l = 0; g.cells && l < m; ++l) {
      const double want = group_error[q][l] / double(g.cells);
      EXPECT_NEAR(g.rows[l].error, want, 1e-4 * want) << "group " << q << " reach " << r.ladder[l];
      if (want < group_error[q][gbest] / double(g.cells)) gbest = l;
    }
    EXPECT_EQ(g.reach, g.cells >= r.min_group_cells ? r.ladder[gbest] : c.reach) << "group " << q;
    for (int row = g.first; row < g.end; ++row) EXPECT_EQ(per_row[std::size_t(row)], g.reach);
  }
  EXPECT_GE(group_cells[1] + group_cells[2] + group_cells[3], r.min_group_cells) << "groups choose for themselves";

  // The same rows, bit for bit, on one thread.
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const acquire::ReachChoice one = acquire::choose_confidence_reach(src, family_prior(), o, r);
  omp_set_num_threads(saved);
  for (std::size_t l = 0; l < m; ++l) EXPECT_EQ(one.rows[l].error, c.rows[l].error) << r.ladder[l];
}

TEST(PriorReach, TheCarryOfTheLogResidualsIsRehearsedOnTheHeldBand) {
  // A bumped material and a prior without the bump: the fit misses the rise towards the light in and above the band.
  const Scan s = band_scan(true);
  const brdf::MemorySamples src(s.angles, s.values, 5);
  acquire::ReachOptions r;
  r.retro_residuals = acquire::LogResidualOptions{};
  const acquire::ReachChoice c = acquire::choose_confidence_reach(src, family_prior(), {}, r);
  ASSERT_TRUE(c.retro_residuals);
  EXPECT_EQ(c.retro_residuals->carried_rows, c.holdout.band_end - 1);  // the kept samples' lowest row less the radius
  std::vector<std::uint8_t> seen(brdf::kMerlCells, 0);
  std::size_t cells = 0;  // the band's cells holding a sample, counted here
  for (std::size_t i = 0; i < s.angles.size() / 4; ++i) {
    const brdf::StdAngles a{s.angles[4 * i], s.angles[4 * i + 1], s.angles[4 * i + 2], s.angles[4 * i + 3]};
    if (!(a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2)) continue;
    const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
    const int row = brdf::merl_cell(cell).theta_d;
    if (row >= c.holdout.band_first && row < c.holdout.band_end && !seen[cell]) cells += (seen[cell] = 1);
  }
  EXPECT_EQ(c.retro_residuals->cells, cells);
  // The samples above the band stand above the fit as the band's do: carried, they put it closer.
  EXPECT_TRUE(c.retro_residuals->carried);
  EXPECT_LT(c.retro_residuals->error_carried, 0.9 * c.retro_residuals->error_plain);
  // The other choices are those made without the rehearsal.
  const acquire::ReachChoice without = acquire::choose_confidence_reach(src, family_prior(), {}, {});
  EXPECT_FALSE(without.retro_residuals);
  EXPECT_EQ(without.reach, c.reach);
  EXPECT_EQ(without.retro_weight, c.retro_weight);
  EXPECT_EQ(without.retro_continued, c.retro_continued);
  // Nothing rehearsed without a band.
  r.retro_ladder.clear();
  EXPECT_FALSE(acquire::choose_confidence_reach(src, family_prior(), {}, r).retro_residuals);
}
