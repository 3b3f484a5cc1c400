// RGL materials as files: the four real RGB files of the RGL database in ../shared (parse, finite values, directional
// albedo below 1, reciprocity statistics printed), and malformed materials refused naming the field.
#include "specula/codec/rgl_bsdf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "grid_fixture.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_export.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

namespace fs = std::filesystem;
const fs::path kRgl = fs::path(SPECULA_SHARED_DIR) / "data" / "brdf" / "rgl";

TEST(RglBsdf, TheRealFilesParseWithFiniteValuesAndAlbedoBelowOne) {
  if (!fs::is_directory(kRgl)) GTEST_SKIP() << kRgl << " is absent (../shared)";
  int files = 0;
  for (const char* name :
       {"aurora_white_rgb.bsdf", "cc_nothern_aurora_rgb.bsdf", "chm_orange_rgb.bsdf", "vch_silk_blue_rgb.bsdf"}) {
    const RglBsdf b = read_rgl_bsdf(kRgl / name);  // from_tensor refuses NaN, Inf and inconsistent shapes
    ++files;
    EXPECT_TRUE(b.rgb) << name;
    EXPECT_EQ(b.theta_i.size(), 8u) << name;
    EXPECT_EQ(b.resolution, 32u) << name;
    EXPECT_FALSE(b.description.empty()) << name;
    const RglEvaluator e(b);
    double top = 0;
    for (float t : b.theta_i) {
      if (t > 1.4f) continue;  // the grazing rows are extrapolated by the renderers' clamped warp
      const auto a = e.albedo(t, 96);
      for (double v : a) {
        EXPECT_TRUE(std::isfinite(v) && v > 0) << name << " theta_i " << t;
        top = std::max(top, v);
      }
    }
    EXPECT_LT(top, 1.0) << name;
    // Reciprocity: f(wi, wo) against f(wo, wi) at cell centres of the MERL grid (every 97th valid cell).
    std::vector<double> rel;
    std::vector<double> f1(3), f2(3);
    for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 97) {
      const auto c = brdf::merl_cell(cell);
      if (!brdf::merl_cell_valid(c)) continue;
      Eigen::Vector3d wi, wo;
      brdf::directions(brdf::merl_cell_centre(c), wi, wo);
      e.eval(wi, wo, f1);
      e.eval(wo, wi, f2);
      const double a = f1[1], bb = f2[1];
      if (a + bb > 1e-6) rel.push_back(std::abs(a - bb) / (0.5 * (a + bb)));
    }
    std::sort(rel.begin(), rel.end());
    ASSERT_FALSE(rel.empty());
    const double median = rel[rel.size() / 2], p90 = rel[rel.size() * 9 / 10];
    std::printf(
        "%s: albedo max %.3f; reciprocity |f(wi,wo) - f(wo,wi)| / mean, green: median %.3f, p90 %.3f over %zu pairs\n",
        name, top, median, p90, rel.size());
    RecordProperty(std::string(name) + "_reciprocity_median", std::to_string(median));
    EXPECT_LT(median, 0.5) << name;  // a measured material tabulated per incident direction is roughly reciprocal
  }
  EXPECT_EQ(files, 4);
}

TEST(RglBsdf, AMeasuredMaterialRoundTripsThroughExport) {
  // A measured-derived grid: the real glossy vinyl evaluated at the MERL cell centres, exported again with specula's
  // own parameterisation and evaluated back. Compared where both directions are within 80 degrees of the normal.
  if (!fs::is_directory(kRgl)) GTEST_SKIP() << kRgl << " is absent (../shared)";
  const MerlBrdf a = rgl_to_merl(read_rgl_bsdf(kRgl / "chm_orange_rgb.bsdf"));
  const MerlBrdf b = rgl_to_merl(export_rgl(a, {}));
  std::vector<double> rel;
  double num = 0, den = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 5) {
    if (!a.has_data(cell) || !b.has_data(cell)) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
    if (wi.z() < 0.17 || wo.z() < 0.17) continue;
    const double w = wi.z() * wo.z();
    for (int c = 0; c < 3; ++c) {
      num += w * std::pow(a.value(c, cell) - b.value(c, cell), 2);
      den += w * std::pow(a.value(c, cell), 2);
      if (a.value(c, cell) > 1e-3) rel.push_back(std::abs(b.value(c, cell) / a.value(c, cell) - 1));
    }
  }
  std::sort(rel.begin(), rel.end());
  const double median = rel[rel.size() / 2], rms = std::sqrt(num / den);
  std::printf("chm_orange re-exported: median relative error %.4f, cos-weighted relative RMS %.4f\n", median, rms);
  // Known gap (docs/brdf.md): off the peak of this very glossy film (D(0) near 5000) the re-export is 4.3 % off in
  // the median, 0.069 relative RMS, with the stored values fitted by least squares (7 % and 0.116 from point
  // samples at the nodes, 12 % with the 128-node ndf and the earlier vndf mixture); the bounds guard against
  // regressions, they are not the goal.
  EXPECT_LT(median, 0.055);
  EXPECT_LT(rms, 0.085);
}

TEST(RglBsdf, ACellIsImportedWithBothDirectionsTabulated) {
  // A Lambertian exported and imported: f = rho / pi everywhere. Where one direction of a cell is grazing, the file's
  // f cos(theta_o) divided by that cosine alone is far off; the import's cosine-weighted mean of both orders is not.
  const auto m = brdf::make_material("green-matte", test::kCodecBands);
  const store::Grid a = test::grid_of(*m);
  const RglBsdf b = export_rgl(a, {});
  const std::vector<float> v = rgl_merl_values(b);
  const RglEvaluator e(b);
  std::vector<double> f(b.channels()), one, both;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; cell += 7) {
    const auto c = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(c)) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(c), wi, wo);
    if (!(std::min(wi.z(), wo.z()) < 0.1 && std::max(wi.z(), wo.z()) > 0.5)) continue;
    const double truth = a.brdf[3 * brdf::kMerlCells + cell] * a.scale;  // the middle band
    e.eval(wi.z() < wo.z() ? wo : wi, wi.z() < wo.z() ? wi : wo, f);     // divided by the grazing cosine
    one.push_back(std::abs(f[3] / truth - 1));
    both.push_back(std::abs(v[3 * brdf::kMerlCells + cell] / truth - 1));
  }
  ASSERT_GT(both.size(), 100u);
  std::sort(one.begin(), one.end());
  std::sort(both.begin(), both.end());
  const double p90_one = one[one.size() * 9 / 10], p90_both = both[both.size() * 9 / 10];
  std::printf("grazing cells: relative error p90 %.4f divided by the grazing cosine, %.4f imported\n", p90_one,
              p90_both);
  EXPECT_LT(p90_both, 0.05);
  EXPECT_LT(p90_both, 0.5 * p90_one);
}

RglBsdf small() {
  RglBsdf b;
  b.description = "small";
  b.theta_i = {0.0f, 1.0f};
  b.ndf_width = b.sigma_width = 3;
  b.ndf.assign(6, 1.0f);
  b.sigma.assign(6, 1.0f);
  b.vndf_width = b.vndf_height = 2;
  b.vndf.assign(8, 1.0f);
  b.resolution = 2;
  b.luminance.assign(8, 1.0f);
  b.wavelengths = {500.0f, 600.0f};
  b.values.assign(16, 0.5f);
  b.valid.assign(1, 0xff);
  return b;
}

std::string error_of(const TensorFile& f) {
  try {
    from_tensor(f, "m.bsdf");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TensorField& field(TensorFile& f, std::string_view name) {
  for (auto& x : f.fields)
    if (x.name == name) return x;
  throw std::logic_error("no field");
}

TEST(RglBsdf, MalformedMaterialsAreRefusedNamingTheField) {
  EXPECT_EQ(error_of(to_tensor(small())), "");
  TensorFile f = to_tensor(small());
  field(f, "ndf").shape = {6};
  EXPECT_NE(error_of(f).find("'ndf' has rank 1"), std::string::npos);
  f = to_tensor(small());
  std::erase_if(f.fields, [](const TensorField& x) { return x.name == "vndf"; });
  EXPECT_NE(error_of(f).find("'vndf' is missing"), std::string::npos);
  RglBsdf nan = small();
  nan.values[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(error_of(to_tensor(nan)).find("'spectra' holds nan"), std::string::npos);
  RglBsdf aniso = small();
  aniso.phi_i = {0.0f, 3.14f};
  aniso.vndf.resize(16, 1.0f);
  aniso.luminance.resize(16, 1.0f);
  aniso.values.resize(32, 1.0f);
  EXPECT_NE(error_of(to_tensor(aniso)).find("anisotropic"), std::string::npos);
  RglBsdf zero = small();
  std::fill(zero.vndf.begin() + 4, zero.vndf.end(), 0.0f);
  EXPECT_NE(error_of(to_tensor(zero)).find("'vndf' is zero everywhere for incident direction 1"), std::string::npos);
  f = to_tensor(small());
  field(f, "theta_i").type = TensorType::float64;
  EXPECT_NE(error_of(f).find("'theta_i' is float64"), std::string::npos);
  RglBsdf order = small();
  order.theta_i = {1.0f, 0.5f};
  EXPECT_NE(error_of(to_tensor(order)).find("'theta_i'"), std::string::npos);
}

}  // namespace
}  // namespace specula::codec
