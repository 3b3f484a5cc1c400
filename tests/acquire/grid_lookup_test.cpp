// A grid read as a material (acquire/simulate.h grid_material): the analytic model's own grid, looked up
// trilinearly, agrees with the closed-form model within the grid's discretisation, better than the nearest cell,
// returns the grid's values at cell centres and a constant material exactly everywhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "specula/acquire/simulate.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"

using namespace specula;
using namespace specula::acquire;

namespace {

std::shared_ptr<const store::Grid> grid_of(const brdf::SpectralModel& model) {
  auto g = std::make_shared<store::Grid>();
  g->wavelengths = model.wavelengths();
  g->brdf.resize(model.bands() * brdf::kMerlCells);
  brdf::evaluate_grid(model, g->brdf);
  return g;
}

// Median over n random configurations (both directions below 80 degrees) of |lookup / model - 1| over every band.
double median_error(const brdf::SpectralModel& lookup, const brdf::SpectralModel& model, std::size_t n) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> a(4 * n);
  for (std::size_t i = 0; i < n; ++i)
    a[4 * i] = std::acos(1 - 0.82 * u(rng)), a[4 * i + 1] = 6.28 * u(rng), a[4 * i + 2] = std::acos(1 - 0.82 * u(rng)),
          a[4 * i + 3] = 6.28 * u(rng);
  std::vector<float> got(n * model.bands()), want(n * model.bands());
  brdf::evaluate_at(lookup, a, got);
  brdf::evaluate_at(model, a, want);
  std::vector<double> e(got.size());
  for (std::size_t i = 0; i < got.size(); ++i) e[i] = std::abs(double(got[i]) / want[i] - 1);
  std::nth_element(e.begin(), e.begin() + std::ptrdiff_t(e.size() / 2), e.end());
  return e[e.size() / 2];
}

TEST(GridLookup, TrilinearAgreesWithTheClosedFormWithinTheGridsDiscretisation) {
  const WavelengthGrid g = WavelengthGrid::parse("420:720:100");
  for (const char* name : {"study-ts", "blue-paint"}) {
    const auto model = brdf::make_material(name, g);
    const auto grid = grid_of(*model);
    const double tri = median_error(*grid_material(grid, g, GridLookup::trilinear), *model, 20000);
    const double near = median_error(*grid_material(grid, g, GridLookup::nearest), *model, 20000);
    EXPECT_LT(tri, 0.003) << name;
    EXPECT_LT(tri, near / 3) << name << ": nearest " << near;
  }
}

TEST(GridLookup, TrilinearReturnsTheGridAtCellCentres) {
  const WavelengthGrid g = WavelengthGrid::parse("450:650:100");
  const auto model = brdf::make_material("red-plastic", g);
  const auto grid = grid_of(*model);
  const auto tri = grid_material(grid, g, GridLookup::trilinear);
  std::mt19937_64 rng(5);
  std::vector<double> out(g.size());
  int checked = 0;
  while (checked < 2000) {
    const std::size_t cell = rng() % brdf::kMerlCells;
    const brdf::MerlCell c = brdf::merl_cell(cell);
    if (!brdf::merl_cell_valid(c)) continue;
    Eigen::Vector3d wi, wo;
    brdf::directions(brdf::merl_cell_centre(c), wi, wo);
    tri->eval(wi, wo, out);
    for (std::size_t k = 0; k < g.size(); ++k) {
      const double want = grid->brdf[k * brdf::kMerlCells + cell];
      ASSERT_NEAR(out[k], want, 1e-4 * want + 1e-7) << "cell " << cell << " band " << k;
    }
    ++checked;
  }
}

TEST(GridLookup, AConstantMaterialComesBackEverywhereAboveTheHorizon) {
  const WavelengthGrid g = WavelengthGrid::parse("500:600:100");
  const auto model = brdf::make_material("green-matte", g);
  const auto tri = grid_material(grid_of(*model), g, GridLookup::trilinear);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> got(g.size()), want(g.size());
  for (int i = 0; i < 20000; ++i) {
    // Up to 89.9 degrees: near the horizon some corners have no data and the others' weights are renormalised.
    const Eigen::Vector3d wi = brdf::direction(1.569 * u(rng), 6.28 * u(rng));
    const Eigen::Vector3d wo = brdf::direction(1.569 * u(rng), 6.28 * u(rng));
    tri->eval(wi, wo, got);
    model->eval(wi, wo, want);
    for (std::size_t k = 0; k < g.size(); ++k) ASSERT_NEAR(got[k], want[k], 1e-6 * want[k]);
  }
}

}  // namespace
