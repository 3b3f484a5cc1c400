// codec/spc_coding.h, what `specula encode` and specula.spc_encode call: each method and basis source gives the bytes
// the lower-level encoders give when called by hand, and a request that makes no sense is refused.
#include <gtest/gtest.h>

#include <memory>

#include "grid_fixture.h"
#include "specula/codec/spc_coding.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

const WavelengthGrid& kGrid = test::kCodecBands;

store::Grid material_grid(const std::string& name) { return test::grid_of(*brdf::make_material(name, kGrid)); }

std::shared_ptr<const store::Basis> learned_pca() {
  auto pca = std::make_shared<store::Basis>();
  pca->method = "pca";
  pca->wavelengths = kGrid;
  pca->mean = Eigen::VectorXd::LinSpaced(7, 0.2, 0.5);
  pca->components = Eigen::MatrixXd::Zero(3, 7);
  for (Eigen::Index j = 0; j < 3; ++j) pca->components(j, 2 * j) = 1;
  return pca;
}

TEST(SpcCoding, EachMethodGivesTheBytesOfItsEncoderCalledByHand) {
  const store::Grid grid = material_grid("cyan-gloss");
  const SpcBoundedOptions bounded{.max_error = 0.02};
  const SpcCoding b = code_grid(grid, {}, 3, bounded, "g");
  EXPECT_EQ(b.bytes, encode_spc(grid, self_basis(grid, 3), bounded, nullptr, "g"));
  EXPECT_EQ(b.max_k, kGrid.size());
  EXPECT_FALSE(b.target || b.k_search);
  const SpcTransformOptions transform{.step = 0.05};
  const SpcCoding t = code_grid(grid, {}, 2, transform, nullptr, "g");
  EXPECT_EQ(t.bytes, encode_spc(grid, self_basis(grid, 2), transform, nullptr, "g"));
  EXPECT_EQ(t.report.output_bytes, t.bytes.size());
  // A learned basis cut to k and extended by `extra` of the grid's residual; k stops where the basis or the bands do.
  const SpcBasisSource learned{.learned = learned_pca(), .reference = "db.h5:pca", .extra = 2};
  const SpcCoding l = code_grid(grid, learned, 3, transform, nullptr, "g");
  const SpcBasis by_hand = augment_basis(coding_basis(*learned.learned, 3, "db.h5:pca"), grid, 2);
  EXPECT_EQ(l.basis.rows, by_hand.rows);
  EXPECT_EQ(l.basis.reference, by_hand.reference);
  EXPECT_EQ(l.bytes, encode_spc(grid, by_hand, transform, nullptr, "g"));
  EXPECT_EQ(l.max_k, 4u);  // the mean and three components; 7 bands less 2 extra would allow 5
}

TEST(SpcCoding, SamplesAreCodedAsTheirEncoderCodesThem) {
  const store::Grid grid = material_grid("cyan-gloss");
  std::vector<double> angles;
  std::vector<float> values;
  for (std::size_t c = 0; c < brdf::kMerlCells; c += 997) {
    if (!(grid.brdf[c] >= 0)) continue;
    const brdf::StdAngles a = brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(c)));
    angles.insert(angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    for (std::size_t q = 0; q < kGrid.size(); ++q) values.push_back(grid.brdf[q * brdf::kMerlCells + c]);
  }
  const SpcSampleSet set{kGrid, angles, values, "1/sr", 1};
  const SpcSamplesOptions options{.rule = {.k = 4, .weights = brdf::Weights::wendland}, .step = 0.02};
  const SpcCoding s = code_samples(set, {}, 2, options, nullptr, "s");
  EXPECT_EQ(s.bytes, encode_spc(set, self_basis(set, 2), options, nullptr, "s"));
  EXPECT_EQ(s.max_k, kGrid.size());
  // To a target at a given k: a search over that one basis, judged against the grid the samples resample to.
  const LightingSuite suite(kGrid, {.size = 16});
  const SpcTargetSearch search{{.de00_mean = 1.0, .de00_p95 = 3.0, .condition_mean = 2.0, .max_trials = 4}, suite};
  const SpcCoding t = code_samples(set, {}, 2, options, &search, "s");
  SpcTargetReport tr;
  SpcKReport kr;
  const auto by_hand = encode_spc_samples_choosing_k(
      set, resample_samples(set, options.rule), [&set](std::size_t) { return self_basis(set, 2); }, 1, options,
      search.target, suite, tr, kr, nullptr, nullptr, "s");
  EXPECT_EQ(t.bytes, by_hand);
  ASSERT_TRUE(t.target);
  EXPECT_EQ(t.target->step, tr.step);
  EXPECT_FALSE(t.k_search);
  EXPECT_FALSE(spc_coding_json(t, nullptr, &search.target, 1.0, "s").contains("k_search"));
}

TEST(SpcCoding, RequestsThatMakeNoSenseAreRefusedByName) {
  const store::Grid grid = material_grid("cyan-gloss");
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const UsageError& e) {
      return std::string(e.what());
    }
    return std::string("nothing thrown");
  };
  EXPECT_NE(message([&] { code_grid(grid, {}, 0, SpcBoundedOptions{}, "g"); }).find("needs k"), std::string::npos);
  EXPECT_NE(message([&] { code_grid(grid, {}, 0, SpcTransformOptions{}, nullptr, "g"); }).find("needs a target"),
            std::string::npos);
  EXPECT_NE(message([&] { code_grid(grid, {.extra = 1}, 2, SpcTransformOptions{}, nullptr, "g"); }).find("extra 1"),
            std::string::npos);
  const std::string bad = message([] { read_basis_source("db.h5", 0, "encode: --basis"); });
  EXPECT_NE(bad.find("encode: --basis"), std::string::npos) << bad;
  EXPECT_NE(bad.find("'db.h5'"), std::string::npos) << bad;
  const SpcBasisSource self = read_basis_source("self", 0, "basis");
  EXPECT_FALSE(self.learned);
  EXPECT_EQ(self.reference, "self");
}

}  // namespace
}  // namespace specula::codec
