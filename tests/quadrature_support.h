#pragma once
// Direct integrals over wavelength for the tests of everything that integrates spectra (XYZ, relighting, uplift,
// rendering): an irregular band grid; integrals on every nm of the 1 nm CIE table by the trapezoid rule written out
// here (not core's trapezoid_weights); the trapezoid rule on the irregular grid's nodes, written out, and a
// rigorous bound on how far it may be from the direct integrals; and the answer a code that wrongly assumed uniform
// spacing would give. A test checks the code against the rule on the nodes to rounding, that rule against the
// direct integral within the bound, and that the uniform-step answer is far outside the rounding tolerance.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <vector>

#include "specula/core/cie.h"
#include "specula/core/wavelengths.h"

namespace specula::test {

/// 31 bands, 400-700 nm at whole nm, mean step 10 nm as on the usual grid but spaced 3 to 5 nm up to 460 nm and
/// 12 to 20 nm beyond: a code that assumed a uniform step would weight the blue half of the bands four times over.
inline WavelengthGrid irregular_grid() {
  const std::vector<double> steps{3,  5,  4,  3,  5,  3,  5,  4,  3,  5,  3,  5,  4,  3,  5,
                                  12, 20, 16, 14, 18, 12, 20, 16, 14, 18, 12, 20, 16, 14, 18};
  std::vector<double> nm{400};
  for (const double h : steps) nm.push_back(nm.back() + h);
  return WavelengthGrid(nm);
}

/// A function of wavelength (nm), evaluated at whole nm by the direct integrals.
using Spectrum = std::function<double(double)>;

/// CIE 1931 2 degree CMF `c` (0 x, 1 y, 2 z) at whole nm `nm` in 360-830, from the embedded 1 nm table.
inline double cmf_at(int c, double nm) {
  const CieTable t = cmf_table(Observer::cie1931_2deg);
  return t.columns[std::size_t(c)][std::size_t(std::lround(nm - t.nm.front()))];
}

/// Integral of f over [a, b] (whole nm) by the trapezoid rule on every nm.
inline double integral_1nm(const Spectrum& f, double a, double b) {
  double s = 0;
  for (double l = a; l < b; l += 1) s += 0.5 * (f(l) + f(l + 1));
  return s;
}

/// The trapezoid rule on `grid`'s own nodes, written out: what a correct code computes from the samples.
inline double integral_on_nodes(const Spectrum& f, const WavelengthGrid& grid) {
  double s = 0;
  for (std::size_t i = 0; i + 1 < grid.size(); ++i) s += 0.5 * (grid[i + 1] - grid[i]) * (f(grid[i]) + f(grid[i + 1]));
  return s;
}

/// What a code that assumed a uniform step would compute: the samples at `grid`'s nodes weighted as if spaced
/// evenly at the mean step (the trapezoid rule in band index times (last - first) / (bands - 1)).
inline double uniform_step_integral(const Spectrum& f, const WavelengthGrid& grid) {
  const double step = (grid.back() - grid.front()) / double(grid.size() - 1);
  double s = 0;
  for (std::size_t i = 0; i + 1 < grid.size(); ++i) s += 0.5 * step * (f(grid[i]) + f(grid[i + 1]));
  return s;
}

/// Bound on how far the trapezoid rule on `grid`'s nodes (whole nm) may be from integral_1nm(f): both rules integrate
/// the function interpolated linearly between whole nm (as core interpolates the CIE table), whose kinks are f's
/// second differences d_l; on an interval [a, b] the coarse rule errs by exactly the sum over the whole nm l inside
/// of d_l (l - a)(b - l) / 2, so the sum of |d_l| (l - a)(b - l) / 2 bounds it whatever the signs.
inline double trapezoid_error_bound(const Spectrum& f, const WavelengthGrid& grid) {
  double bound = 0;
  for (std::size_t i = 0; i + 1 < grid.size(); ++i) {
    const double a = grid[i], b = grid[i + 1];
    for (double l = a + 1; l < b; l += 1) bound += std::abs(f(l - 1) - 2 * f(l) + f(l + 1)) * (l - a) * (b - l) / 2;
  }
  return bound;
}

/// A quantity computed from integrals, evaluated at the direct 1 nm integrals (with a tolerance: the integrals'
/// error bounds on the grid propagated to first order, |dF/dI_i| bound_i summed, derivatives by central
/// differences), at the trapezoid rule on the grid's nodes (what the code under test must return, to rounding), and
/// at the uniform-step integrals (what it would return with that mistake).
struct Propagated {
  Eigen::VectorXd direct, tolerance, nodes, uniform_step;
};

/// Evaluates `formula` (integrals -> quantities) on the integrals of `integrands` over the grid's span: direct,
/// on the grid's nodes and with a uniform step, and the tolerance of the direct values.
inline Propagated propagate(const std::vector<Spectrum>& integrands, const WavelengthGrid& grid,
                            const std::function<Eigen::VectorXd(const std::vector<double>&)>& formula) {
  std::vector<double> direct, bound, nodes, uniform;
  for (const auto& f : integrands) {
    direct.push_back(integral_1nm(f, grid.front(), grid.back()));
    bound.push_back(trapezoid_error_bound(f, grid));
    nodes.push_back(integral_on_nodes(f, grid));
    uniform.push_back(uniform_step_integral(f, grid));
  }
  Propagated p;
  p.direct = formula(direct);
  p.nodes = formula(nodes);
  p.uniform_step = formula(uniform);
  p.tolerance = Eigen::VectorXd::Zero(p.direct.size());
  for (std::size_t i = 0; i < direct.size(); ++i) {
    const double d = 1e-6 * std::max(std::abs(direct[i]), 1e-12);
    std::vector<double> up = direct, down = direct;
    up[i] += d;
    down[i] -= d;
    p.tolerance += ((formula(up) - formula(down)) / (2 * d)).cwiseAbs() * bound[i];
  }
  return p;
}

/// The checks of a quantity `got` that the code computed on the grid: it is the trapezoid rule on the grid's nodes
/// within `rounding` (times max(1, |value|)), which is the direct integral within the propagated bound, and the
/// uniform-step answer misses it by more than 100 times the rounding tolerance (so the test fails on that mistake).
inline void expect_integrals(const Eigen::VectorXd& got, const Propagated& want, double rounding) {
  ASSERT_EQ(got.size(), want.direct.size());
  double uniform_miss = 0;
  for (Eigen::Index k = 0; k < got.size(); ++k) {
    const double tol = rounding * std::max(1.0, std::abs(want.nodes[k]));
    EXPECT_NEAR(got[k], want.nodes[k], tol) << "value " << k << " against the trapezoid rule on the nodes";
    EXPECT_NEAR(want.nodes[k], want.direct[k], want.tolerance[k]) << "value " << k << " against the direct integral";
    uniform_miss = std::max(uniform_miss, std::abs(want.uniform_step[k] - got[k]) / tol);
  }
  EXPECT_GT(uniform_miss, 100) << "a uniform-step quadrature would pass this test";
}

}  // namespace specula::test
