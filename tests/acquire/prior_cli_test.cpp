// `specula prior build` and `specula resample --prior` from the command line on small analytic materials: the
// prior is stored with its training list (the captured material left out by --exclude), every valid cell of the
// result has data, the confidence grid lies beside it, the kd-tree's reach is chosen from the scan unless given, the
// grid does not depend on --prior-block-mb, and a bad prior name, reach or peak rows is one line leaving the store
// alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "specula/acquire/prior.h"
#include "specula/acquire/prior_reach.h"
#include "specula/acquire/retro_trend.h"
#include "specula/core/brdf_geometry.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula {
namespace {

using test::run_specula;

TEST(PriorCli, BuildsLeavingTheCaptureOutAndResamplesEveryValidCellWithConfidenceBeside) {
  test::ScratchDir dir;
  const std::string db = (dir / "db.h5").string(), wl = " --wavelengths 400:700:100";
  for (const char* m : {"blue-paint", "gold", "green-matte", "study-ts", "cyan-gloss"})
    ASSERT_EQ(run_specula(std::string("synth-brdf ") + m + wl + " -o '" + db + ":" + m + "'").status, 0) << m;
  auto r = run_specula("prior build '" + db + "' --exclude cyan-gloss --channels 3 -o '" + db + "' --name p");
  ASSERT_EQ(r.status, 0) << r.output;
  const acquire::BrdfPrior p = acquire::read_prior(store::Store::open(db), "p");
  EXPECT_EQ(p.training.size(), 4u);
  EXPECT_EQ(p.retro_exponents.size(), std::size_t(acquire::kRetroLearnedRows));
  EXPECT_NE(r.output.find("p by band width 1-8 rows: "), std::string::npos) << r.output;
  for (const auto& t : p.training) EXPECT_EQ(t.find("cyan-gloss"), std::string::npos) << t;

  r = run_specula("synth-samples cyan-gloss --geometry random -n 40000" + wl + " -o '" + db + ":scan'");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -o '" + (dir / "out.h5").string() + ":g' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "valid_cells"), double(acquire::valid_cells().size()));
  // The reach chosen by default: one of the ladder's, reported with the validation's rows.
  const double reach = test::json_number(r.output, "confidence_reach");
  const std::vector<double> ladder = acquire::ReachOptions{}.ladder;
  EXPECT_NE(std::find(ladder.begin(), ladder.end(), reach), ladder.end()) << r.output;
  EXPECT_EQ(test::json_number(r.output, "reach"), reach) << r.output;
  EXPECT_GT(test::json_number(r.output, "held_cells"), 0) << r.output;
  // The prior's components read one store chunk at a time instead of all at once: the same grid, bit for bit.
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' --prior-block-mb 1 -o '" +
                  (dir / "out.h5").string() + ":g1'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Store out = store::Store::open(dir / "out.h5");
  const store::Grid g = out.read_grid("g"), c = out.read_grid("g.confidence");
  EXPECT_EQ(out.read_grid("g1").brdf, g.brdf);
  EXPECT_EQ(c.units, "confidence");
  for (const std::uint32_t cell : acquire::valid_cells()) {
    ASSERT_GE(g.brdf[cell], 0.0f) << cell;
    ASSERT_GE(c.brdf[cell], 0.0f) << cell;
    ASSERT_LE(c.brdf[cell], 1.0f) << cell;
  }

  // A reach given is used as it is.
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -o '" + (dir / "out.h5").string() +
                  ":f' --confidence-reach 0.25 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "confidence_reach"), 0.25);
  EXPECT_EQ(r.output.find("confidence_reach_auto"), std::string::npos) << r.output;
  for (const char* bad :
       {"--confidence-reach 0.1x", "--confidence-reach auto --prior-residuals", "--peak-rows 90", "--peak-rows 2x"}) {
    r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -o '" + (dir / "out.h5").string() + ":b' " +
                    bad);
    EXPECT_NE(r.status, 0) << bad;
    EXPECT_NE(r.output.find(std::string(bad).substr(0, std::string(bad).find(' '))), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  r = run_specula("resample '" + db + "' scan --model ggx -o '" + (dir / "m.spgrid").string() +
                  "' --confidence-reach auto");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--confidence-reach auto: only with --prior"), std::string::npos) << r.output;

  // A rig's scan leaves theta_d below its first light's half angle unseen: auto reports the band it chose a weight
  // for; --blend-in-retro holds no band out and chooses none.
  r = run_specula("synth-samples cyan-gloss --sphere-px 60 --lights 30 --light-step 5" + wl + " -o '" + db + ":rig'");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "out.h5").string() + ":r' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(test::json_number(r.output, "unseen_rows"), 5) << r.output;
  const double w = test::json_number(r.output.substr(r.output.find("\"retro_band\"")), "weight");
  EXPECT_TRUE(w == 0 || w == 0.25 || w == 0.5 || w == 0.75 || w == 1) << r.output;
  EXPECT_NE(r.output.find("\"retro_cells\":"), std::string::npos) << r.output;  // each theta_h group's band weight
  EXPECT_NE(r.output.find("\"continued\":"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("\"continued_rows\":[]"), std::string::npos) << r.output;
  const std::string defaults = r.output;
  r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "out.h5").string() +
                  ":rb' --blend-in-retro --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"weight\":null"), std::string::npos) << r.output;
  // The cap's weight is chosen by default and reported, with the cells the ceiling bounded; --prior-alone-in-cap
  // chooses none.
  EXPECT_NE(r.output.find("\"cap_weight_auto\":{\"weight\":"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"bounded_cells\":"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"energy_bounded_cells\":"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"blend\":\"log\""), std::string::npos) << r.output;
  EXPECT_GT(test::json_number(r.output, "blend_epsilon"), 0) << r.output;
  // The samples' log residuals correct the blend by default, one pass over 3 x 3 x 3 cells, carried into the retro
  // band (its five rows less the radius) when the rehearsal one band higher says so; the settings are given on the
  // command line; --no-log-residuals leaves the blend.
  const std::string lr = defaults.substr(defaults.find("\"log_residuals\":{\"radius\":1,\"passes\":1,"));
  const bool carried = defaults.find("\"residual_carry\":{\"carried\":true,") != std::string::npos;
  EXPECT_TRUE(carried || defaults.find("\"residual_carry\":{\"carried\":false,") != std::string::npos) << defaults;
  EXPECT_EQ(test::json_number(lr, "carried_rows"), carried ? 4 : 0) << defaults;
  EXPECT_NE(r.output.find("\"residual_carry\":null"), std::string::npos) << r.output;  // no band, no rehearsal
  EXPECT_GT(test::json_number(lr, "corrected_cells"), 1000) << r.output;
  // The band's phi_d dependence is settled last, over its five rows; --no-retro-pole leaves it (below).
  const std::string pole = defaults.substr(defaults.find("\"retro_pole\":{\"rows\":5,"));
  EXPECT_GT(test::json_number(pole, "settled_cells"), 10000) << defaults;
  // The theta_h rows round the peak are judged from the scan by default in groups of 5 rows, each group settled by
  // its share; the log residuals span the rings of the rows chosen, a multiple of 5 (--peak-rows N forces them, below).
  const std::string chosen = defaults.substr(defaults.find("\"peak_rows_auto\":{\"rows\":"));
  const double rows = test::json_number(chosen, "rows");
  EXPECT_TRUE(rows >= 0 && rows <= 20 && std::fmod(rows, 5) == 0) << defaults;
  EXPECT_EQ(test::json_number(lr, "ring_rows"), rows) << defaults;
  EXPECT_NE(chosen.find("\"grid_spread\":"), std::string::npos) << defaults;
  const bool settled = defaults.find("\"peak_rows\":{\"rows\":") != std::string::npos;
  EXPECT_TRUE(settled || rows == 0) << defaults;
  EXPECT_EQ(settled, chosen.find("\"keep\":0.") != std::string::npos) << defaults;  // some group keeps under all
  EXPECT_LT(test::json_number(lr, "rms_after"), test::json_number(lr, "rms_before")) << r.output;
  r = run_specula(
      "resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "out.h5").string() +
      ":rl' --log-residual-radius 2 --log-residual-passes 2 --log-residuals-in-retro --peak-rows 20 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  // --peak-rows 20: up to theta_h row 20, the log residuals taken over whole phi_d rings and the rings settled
  EXPECT_EQ(r.output.find("peak_rows_auto"), std::string::npos) << r.output;
  const std::string peak = r.output.substr(r.output.find("\"peak_rows\":{\"rows\":20,"));
  EXPECT_GT(test::json_number(peak, "settled_cells"), 10000) << r.output;
  // the band of five theta_d rows less the radius
  EXPECT_NE(r.output.find("\"log_residuals\":{\"radius\":2,\"passes\":2,\"ring_rows\":20,\"carried_rows\":3,"),
            std::string::npos)
      << r.output;
  r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "out.h5").string() +
                  ":ra' --prior-alone-in-cap --no-ceiling --linear-blend --no-retro-continuation "
                  "--retro-weight-overall --no-log-residuals --no-energy-bound --no-retro-pole --peak-rows 0 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const double overall = test::json_number(r.output.substr(r.output.find("\"retro_band\"")), "weight");
  for (std::size_t at = r.output.find("\"retro_weight\":"); at != std::string::npos;
       at = r.output.find("\"retro_weight\":", at + 1))
    EXPECT_EQ(test::json_number(r.output.substr(at), "retro_weight"), overall) << r.output;
  EXPECT_NE(r.output.find("\"continued\":false,\"continued_rows\":[]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"blend\":\"linear\""), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("cap_weight_auto"), std::string::npos) << r.output;
  EXPECT_EQ(test::json_number(r.output, "bounded_cells"), 0) << r.output;
  EXPECT_EQ(r.output.find("log_residuals"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("retro_pole"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("peak_rows"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"residual_carry\":null"), std::string::npos) << r.output;  // nothing to carry
  // The energy bound is on by default (floor 2, kappa 2) and off with --no-energy-bound, as the provenance says.
  const store::Store bounded = store::Store::open(dir / "out.h5");
  EXPECT_NE(bounded.read_grid("r").provenance.importer.find(" energy_bound=on floor=2 kappa=2 "), std::string::npos);
  EXPECT_NE(bounded.read_grid("ra").provenance.importer.find(" energy_bound=off "), std::string::npos);
  EXPECT_NE(bounded.read_grid("r").provenance.importer.find(" retro_pole=on rows=5 "), std::string::npos);
  EXPECT_NE(bounded.read_grid("ra").provenance.importer.find(" retro_pole=off "), std::string::npos);
  EXPECT_NE(bounded.read_grid("rl").provenance.importer.find(" peak_rows=on rows=20 "), std::string::npos);
  EXPECT_NE(bounded.read_grid("r").provenance.importer.find(settled ? " keep=" : " peak_rows=off chosen "),
            std::string::npos);
  EXPECT_NE(bounded.read_grid("ra").provenance.importer.find(" peak_rows=off "), std::string::npos);
  const std::string said = bounded.read_grid("r").provenance.importer;  // the carry's choice, as the report says
  EXPECT_NE(said.find(carried ? " retro_residuals=carried " : " retro_residuals=plain "), std::string::npos) << said;
  EXPECT_EQ(test::json_number(r.output, "energy_bounded_cells"), 0) << r.output;
  // --retro-rise: after everything else, the band's rows from theta_h row 45 on each scaled by one factor, the prior's
  // map applied to the result's own shoulder; every other cell as without it.
  r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "rise.h5").string() +
                  ":rr' --retro-rise --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"retro_rise\":{\"rows\":5,\"factors\":["), std::string::npos) << r.output;
  EXPECT_EQ(defaults.find("retro_rise"), std::string::npos) << defaults;
  const store::Grid plain = bounded.read_grid("r"), risen = store::Store::open(dir / "rise.h5").read_grid("rr");
  EXPECT_NE(risen.provenance.importer.find(" retro_rise=on rows=5 "), std::string::npos) << risen.provenance.importer;
  EXPECT_NE(plain.provenance.importer.find(" retro_rise=off "), std::string::npos) << plain.provenance.importer;
  std::vector<double> factor(5, 0.0);
  std::size_t changed = 0;
  for (std::size_t at = 0; at < plain.brdf.size(); ++at) {
    const brdf::MerlCell c = brdf::merl_cell(at % brdf::kMerlCells);
    if (c.theta_h < 45 || c.theta_d >= 5 || !(plain.brdf[at] > 0)) {
      ASSERT_EQ(risen.brdf[at], plain.brdf[at]) << at;
      continue;
    }
    double& f = factor[std::size_t(c.theta_d)];
    if (f == 0) f = double(risen.brdf[at]) / plain.brdf[at];
    ASSERT_NEAR(risen.brdf[at], plain.brdf[at] * f, 1e-5 * plain.brdf[at]) << at;
    changed += risen.brdf[at] != plain.brdf[at];
  }
  EXPECT_GT(changed, 10000u);
  {  // a prior written before the maps were learned (version 3) is refused in one line, the output not written
    acquire::BrdfPrior old = acquire::read_prior(store::Store::open(db), "p");
    old.retro_rise.clear();
    store::StoreWriter w(dir / "old.h5", {});
    acquire::write_prior(w, "p3", old);
    w.commit();
  }
  r = run_specula("resample '" + db + "' rig --prior '" + (dir / "old.h5").string() + ":p3' -o '" +
                  (dir / "none.h5").string() + ":g' --retro-rise");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("old.h5:p3' holds no retro rise maps"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "none.h5"));
  for (const char* flag : {"--no-log-residuals-in-retro", "--log-residuals-in-retro"}) {  // forced: not rehearsed
    r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "forced.h5").string() + ":rn' " +
                    flag + " --replace --json");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("\"residual_carry\":null"), std::string::npos) << r.output;
    const std::string forced = r.output.substr(r.output.find("\"log_residuals\":{\"radius\":1,"));
    EXPECT_EQ(test::json_number(forced, "carried_rows"), flag[2] == 'n' ? 0 : 4) << r.output;
  }
  r = run_specula("resample '" + db + "' rig --prior '" + db + ":p' -o '" + (dir / "forced.h5").string() +
                  ":rx' --no-log-residuals-in-retro --log-residuals-in-retro");
  EXPECT_NE(r.status, 0) << r.output;  // the two exclude each other

  // Exchange files: the grid and its confidence beside it, and no temporary left.
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":p' -o '" + (dir / "x.spgrid").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "x.spgrid"));
  EXPECT_TRUE(std::filesystem::exists(dir / "x.confidence.spgrid"));
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();

  const std::string before = test::read_bytes(dir / "out.h5");
  r = run_specula("resample '" + db + "' scan --prior '" + db + ":nope' -o '" + (dir / "out.h5").string() + ":h'");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("db.h5: no prior 'nope' (priors: p"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_EQ(test::read_bytes(dir / "out.h5"), before);
}

}  // namespace
}  // namespace specula
