// The least-squares fit of an RGL file's stored values: its objective, written here from the renderers' evaluation
// (RglEvaluator::eval at every MERL cell centre with either direction tabulated), is lower at the fitted values than
// at the point samples it starts from and than at perturbations of them.
#include "specula/codec/rgl_fit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "grid_fixture.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_export.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

// Sum over the cells with data of (cos theta_i cos theta_o)^p / max(Y, floor * median Y)^2 times the squared error
// of every channel, both directions tabulated in turn; Y the mean over channels.
double objective(const RglBsdf& b, const store::Grid& g, const RglFitSettings& s) {
  const std::size_t C = g.bands();
  std::vector<double> y(brdf::kMerlCells, -1.0), have;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    if (!brdf::merl_cell_valid(brdf::merl_cell(cell))) continue;
    double sum = 0;
    for (std::size_t c = 0; c < C; ++c) sum += g.brdf[c * brdf::kMerlCells + cell] / double(C);
    y[cell] = sum;
    have.push_back(sum);
  }
  std::sort(have.begin(), have.end());
  const double floor = s.floor * have[have.size() / 2];
  const RglEvaluator e(b);
  std::vector<double> f(C);
  double total = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    if (y[cell] < 0) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), wi, wo);
    const double w = std::pow(wi.z() * wo.z(), s.cosine_power) / std::pow(std::max(y[cell], floor), 2);
    for (int order = 0; order < 2; ++order) {
      order == 0 ? e.eval(wi, wo, f) : e.eval(wo, wi, f);
      for (std::size_t c = 0; c < C; ++c) total += w * std::pow(f[c] - g.brdf[c * brdf::kMerlCells + cell], 2);
    }
  }
  return total;
}

TEST(RglFit, TheFitMinimisesItsObjective) {
  const store::Grid g = test::grid_of(*brdf::make_material("red-plastic", test::kCodecBands));
  RglExportSettings settings{.theta_i = 4, .resolution = 12, .least_squares = false};
  settings.fit.prior = 1e-9;  // the Tikhonov term out of the way: the objective above is all that is minimised
  const RglBsdf sampled = export_rgl(g, settings);
  const std::vector<double> lum(g.bands(), 1.0 / double(g.bands()));
  RglBsdf fitted = sampled;
  rgl_fit_values(fitted, g.brdf, 1.0, lum, settings.fit);
  const double at_fit = objective(fitted, g, settings.fit), at_samples = objective(sampled, g, settings.fit);
  std::printf("objective: point samples %.6g, fitted %.6g\n", at_samples, at_fit);
  EXPECT_LT(at_fit, 0.5 * at_samples);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.02);
  for (int k = 0; k < 2; ++k) {
    RglBsdf moved = fitted;
    for (auto& v : moved.values) v = float(v * (1 + noise(rng)));
    EXPECT_GT(objective(moved, g, settings.fit), at_fit) << "perturbation " << k;
  }
}

TEST(RglFit, MismatchedSizesAreRefused) {
  const store::Grid g = test::grid_of(*brdf::make_material("green-matte", test::kCodecBands));
  RglBsdf b = export_rgl(g, {.theta_i = 2, .resolution = 4, .least_squares = false});
  const std::vector<double> lum(g.bands(), 1.0);
  EXPECT_THROW(rgl_fit_values(b, std::span<const float>(g.brdf).first(10), 1.0, lum, {}), UsageError);
  EXPECT_THROW(rgl_fit_values(b, g.brdf, 1.0, std::span<const double>(lum).first(2), {}), UsageError);
  EXPECT_THROW(rgl_fit_values(b, g.brdf, 1.0, lum, {.floor = 0}), UsageError);
}

}  // namespace
}  // namespace specula::codec
