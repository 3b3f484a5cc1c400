#include "specula/codec/spc_eval.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "grid_fixture.h"
#include "specula/codec/environment.h"
#include "specula/codec/render.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid& kGrid = test::kCodecBands;

Eigen::VectorXd ramp(double a, double b) { return Eigen::VectorXd::LinSpaced(Eigen::Index(kGrid.size()), a, b); }

// A Torrance-Sparrow grid coded on its own k-spectrum basis, kept both as coefficients and decoded to a grid.
struct Coded {
  SpcCoefficients coefficients;
  store::Grid grid;
};
enum class SpcMethod { bounded, transform };
const Coded& coded(std::size_t k, SpcMethod method = SpcMethod::bounded) {
  static const store::Grid g =
      test::grid_of(brdf::TorranceSparrow(kGrid, Eigen::VectorXd::Constant(7, 0.15), ramp(1.55, 1.45), ramp(0.5, 0.1)));
  static std::map<std::pair<std::size_t, SpcMethod>, Coded> cache;
  const auto key = std::make_pair(k, method);
  if (!cache.contains(key)) {
    SpcCoefficients c = decode_spc_coefficients(
        method == SpcMethod::bounded ? encode_spc(g, self_basis(g, k), SpcBoundedOptions{.max_error = 0.01})
                                     : encode_spc(g, self_basis(g, k), SpcTransformOptions{.step = 0.01}),
        "test.spc");
    store::Grid grid = expand_spc(c);
    cache.emplace(key, Coded{std::move(c), std::move(grid)});
  }
  return cache.at(key);
}

// Random direction pairs (n x 3 floats each, not normalised): a third uniform over the upper hemisphere, a third
// grazing (theta within 2 degrees of the horizon) and a third near the specular peak (wo the mirror of wi, turned
// by up to a degree).
void direction_pairs(std::size_t n, std::uint32_t seed, std::vector<float>& wi, std::vector<float>& wo) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  auto hemisphere = [&](double min_theta) {
    const double ct = std::cos(min_theta) * u(rng), st = std::sqrt(1 - ct * ct), p = 2 * std::numbers::pi * u(rng);
    return Eigen::Vector3d(st * std::cos(p), st * std::sin(p), ct);
  };
  wi.resize(3 * n);
  wo.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d a, b;
    switch (i % 3) {
      case 0:
        a = hemisphere(0), b = hemisphere(0);
        break;
      case 1:
        a = hemisphere(88 * std::numbers::pi / 180), b = hemisphere(0);
        break;
      default: {
        a = hemisphere(0);
        const Eigen::Vector3d jitter(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        b = Eigen::Vector3d(-a.x(), -a.y(), a.z()) + 0.035 * jitter;
      }
    }
    const double la = 0.5 + u(rng), lb = 0.5 + u(rng);
    for (int c = 0; c < 3; ++c)
      wi[3 * i + std::size_t(c)] = float(la * a[c]), wo[3 * i + std::size_t(c)] = float(lb * b[c]);
  }
}

std::size_t reference_cell(const float* wi, const float* wo) {
  return brdf::merl_index(
      brdf::merl_cell(brdf::half_diff(Eigen::Vector3d(wi[0], wi[1], wi[2]), Eigen::Vector3d(wo[0], wo[1], wo[2]))));
}

TEST(SpcEval, CellsEqualTheDoubleLookupOnRandomPairs) {
  std::vector<float> wi, wo;
  direction_pairs(3'000'000, 7, wi, wo);
  std::vector<std::uint32_t> cells(wi.size() / 3);
  merl_indices(wi, wo, cells);
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::size_t ref = reference_cell(&wi[3 * i], &wo[3 * i]);
    if (cells[i] == ref) continue;
    ++mismatches;
    const brdf::MerlCell a = brdf::merl_cell(std::size_t(cells[i])), b = brdf::merl_cell(ref);
    EXPECT_LE(std::abs(a.theta_h - b.theta_h) + std::abs(a.theta_d - b.theta_d) + std::abs(a.phi_d - b.phi_d), 1) << i;
  }
  EXPECT_LT(double(mismatches) / double(cells.size()), 1e-5);
}

TEST(SpcEval, CellsAtCellCentresAndDegenerateDirectionsEqualTheDoubleLookup) {
  std::vector<float> wi, wo;
  for (std::size_t c = 0; c < N; c += 97) {
    Eigen::Vector3d i, o;
    brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(c)), i, o);
    for (int k = 0; k < 3; ++k) wi.push_back(float(i[k])), wo.push_back(float(o[k]));
  }
  const std::vector<std::array<float, 6>> odd = {{0, 0, 1, 0, 0, 1},
                                                 {1, 0, 0, -1, 0, 0},
                                                 {0, 0, 0, 0, 0, 1},
                                                 {0, 0, 1, 0, 0, -1},
                                                 {0.6f, 0, 0.8f, -0.6f, 0, 0.8f},
                                                 {0, 0, 1, NAN, 0, 1},
                                                 {0, 1, 0, 0, -1, 1e-3f}};
  for (const auto& p : odd)
    for (int k = 0; k < 3; ++k) wi.push_back(p[std::size_t(k)]), wo.push_back(p[std::size_t(k) + 3]);
  std::vector<std::uint32_t> cells(wi.size() / 3);
  merl_indices(wi, wo, cells);
  for (std::size_t i = 0; i < cells.size(); ++i) EXPECT_EQ(cells[i], reference_cell(&wi[3 * i], &wo[3 * i])) << i;
}

void expect_matches_decoded_grid(std::size_t k, SpcMethod method = SpcMethod::bounded) {
  const Coded& c = coded(k, method);
  const SpcBrdf f(SpcCoefficients(c.coefficients));
  const std::size_t b = f.bands();
  std::vector<float> wi, wo;
  direction_pairs(300'000, std::uint32_t(k), wi, wo);
  const std::size_t n = wi.size() / 3;
  std::vector<float> out(n * b), one(b);
  f.evaluate(wi, wo, out);
  std::size_t with_data = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t cell = reference_cell(&wi[3 * i], &wo[3 * i]);
    double magnitude = 0;
    for (std::size_t j = 0; j < k; ++j) magnitude += std::abs(double(c.coefficients.values[cell * k + j]));
    magnitude *= c.coefficients.scale;
    const bool data = c.grid.brdf[cell] >= 0;
    with_data += data;
    const bool single = f.evaluate(Eigen::Vector3d(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                                   Eigen::Vector3d(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]), one);
    ASSERT_EQ(single, data) << i;
    for (std::size_t band = 0; band < b; ++band) {
      const double expect = data ? double(c.grid.brdf[band * N + cell]) * c.grid.scale : 0.0;
      ASSERT_NEAR(out[i * b + band], expect, 1e-6 * magnitude + 1e-30) << "pair " << i << " band " << band;
      ASSERT_EQ(one[band], out[i * b + band]) << "pair " << i << " band " << band;
    }
  }
  EXPECT_GT(with_data, n / 2);
}

TEST(SpcEval, EqualsDecodingToAGridThenLookingUpForK3) { expect_matches_decoded_grid(3); }
TEST(SpcEval, EqualsDecodingToAGridThenLookingUpForK6) { expect_matches_decoded_grid(6); }
TEST(SpcEval, EqualsDecodingToAGridThenLookingUpForATransformCodedFile) {
  expect_matches_decoded_grid(3, SpcMethod::transform);
}

TEST(SpcEval, CellsWithoutDataGiveZeroAndFalse) {
  const SpcBrdf f(SpcCoefficients(coded(3).coefficients));
  std::vector<float> out(f.bands(), 1.0f);
  // Both directions below the horizon of the cell centres: theta_h = 0, theta_d near 90 degrees.
  std::size_t cell = 0;
  while (f.has_data(cell)) ++cell;
  f.evaluate_cell(cell, out);
  for (float v : out) EXPECT_EQ(v, 0.0f);
  Eigen::Vector3d i, o;
  brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(cell)), i, o);
  std::fill(out.begin(), out.end(), 1.0f);
  EXPECT_FALSE(f.evaluate(i, o, out));
  for (float v : out) EXPECT_EQ(v, 0.0f);
}

// Pairs are expanded four, two or one at a time, by the block's remainder: every way gives what one call a pair gives.
TEST(SpcEval, TheArrayCallEqualsOneCallAPairForAnyNumberOfPairs) {
  const SpcBrdf f(SpcCoefficients(coded(6).coefficients));
  const std::size_t b = f.bands();
  std::vector<float> wi, wo;
  direction_pairs(263, 5, wi, wo);  // a block of 256, then 4 + 2 + 1
  for (const std::size_t n : {1, 2, 3, 5, 7, 263}) {
    std::vector<float> out(n * b), one(b);
    f.evaluate(std::span(wi).first(3 * n), std::span(wo).first(3 * n), out);
    for (std::size_t i = 0; i < n; ++i) {
      f.evaluate(Eigen::Vector3d(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                 Eigen::Vector3d(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]), one);
      for (std::size_t band = 0; band < b; ++band) ASSERT_EQ(one[band], out[i * b + band]) << n << " pairs, pair " << i;
    }
  }
}

TEST(SpcEval, ResultsDoNotDependOnTheThreadCount) {
  const SpcBrdf f(SpcCoefficients(coded(6).coefficients));
  std::vector<float> wi, wo;
  direction_pairs(200'000, 3, wi, wo);
  std::vector<float> one(wi.size() / 3 * f.bands()), two(one.size());
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  f.evaluate(wi, wo, one);
  omp_set_num_threads(2);
  f.evaluate(wi, wo, two);
  omp_set_num_threads(threads);
  EXPECT_EQ(one, two);
}

TEST(SpcEval, HoldsAtMostAQuarterOfTheFloat32GridForKUpTo7) {
  for (std::size_t k = 1; k <= 7; ++k) {
    SpcCoefficients c;
    c.wavelengths = WavelengthGrid::range(400, 700, 10);
    c.basis = Eigen::MatrixXd::Identity(Eigen::Index(k), 31);
    c.values.assign(k * N, 0.0f);
    c.valid.assign(N, 1);
    const SpcBrdf f(std::move(c));
    EXPECT_LE(f.memory_bytes(), 31 * N * 4 / 4) << "k = " << k;
    EXPECT_GE(f.memory_bytes(), k * N * 4) << "k = " << k;
  }
}

TEST(SpcEval, RenderingFromTheCodeEqualsRenderingTheDecodedGrid) {
  const Coded& c = coded(3);
  const SpcBrdf f(SpcCoefficients(c.coefficients));
  const Environment env = default_environment(kGrid);
  const SphereRenders grid = render_spheres({&c.grid}, env, 48);
  const std::vector<const SpcBrdf*> brdfs = {&f};
  const SphereRenders code = render_spheres(brdfs, env, 48);
  ASSERT_EQ(code.covered, grid.covered);
  EXPECT_EQ(code.white, grid.white);
  const float peak = *std::max_element(grid.xyz[0].begin(), grid.xyz[0].end());
  ASSERT_GT(peak, 0);
  for (std::size_t i = 0; i < grid.xyz[0].size(); ++i) ASSERT_NEAR(code.xyz[0][i], grid.xyz[0][i], 1e-6 * peak) << i;

  const auto weights = rgb_weights(kGrid, illuminant("D65", kGrid));
  const Eigen::Vector3d light(0.3, -0.2, 0.9);
  const SphereImage a = render_sphere(grid_to_merl(c.grid, weights).brdf, 64, light);
  const SphereImage b = render_sphere(f, weights, 64, light);
  ASSERT_EQ(a.covered, b.covered);
  const float top = *std::max_element(a.linear.begin(), a.linear.end());
  ASSERT_GT(top, 0);
  for (std::size_t i = 0; i < a.linear.size(); ++i) ASSERT_NEAR(b.linear[i], a.linear[i], 1e-6 * top) << i;
}

TEST(SpcEval, RenderingFromTheCodeDoesNotDependOnTheThreadCount) {
  const SpcBrdf f(SpcCoefficients(coded(3).coefficients));
  const std::vector<const SpcBrdf*> brdfs = {&f};
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const SphereRenders one = render_spheres(brdfs, default_environment(kGrid), 40);
  omp_set_num_threads(2);
  const SphereRenders two = render_spheres(brdfs, default_environment(kGrid), 40);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.xyz, two.xyz);
}

TEST(SpcEval, MismatchedSpansAndBadCoefficientsAreRefused) {
  const SpcBrdf f(SpcCoefficients(coded(3).coefficients));
  std::vector<float> wi(6, 0.5f), wo(6, 0.5f), out(2 * f.bands());
  EXPECT_NO_THROW(f.evaluate(wi, wo, out));
  std::vector<float> short_wo(3, 0.5f), odd(5, 0.5f), small(out.size() - 1);
  std::vector<float> one(f.bands() + 1);
  std::vector<std::uint32_t> cells(1);
  EXPECT_THROW(f.evaluate(wi, short_wo, out), UsageError);
  EXPECT_THROW(f.evaluate(odd, odd, out), UsageError);
  EXPECT_THROW(f.evaluate(wi, wo, small), UsageError);
  EXPECT_THROW(f.evaluate(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1), one), UsageError);
  EXPECT_THROW(f.evaluate_cell(N, std::span(out).first(f.bands())), UsageError);
  EXPECT_THROW(merl_indices(wi, wo, cells), UsageError);
  SpcCoefficients bad = coded(3).coefficients;
  bad.values.pop_back();
  EXPECT_THROW(SpcBrdf{std::move(bad)}, UsageError);
  SpcCoefficients unscaled = coded(3).coefficients;
  unscaled.scale = 0;
  EXPECT_THROW(SpcBrdf{std::move(unscaled)}, UsageError);
  const std::vector<const SpcBrdf*> brdfs = {&f};
  EXPECT_THROW(render_spheres(brdfs, default_environment(WavelengthGrid::range(400, 700, 10)), 16), InputError);
  EXPECT_THROW(render_sphere(f, Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, 4), 16, Eigen::Vector3d(0, 0, 1)),
               UsageError);
}

}  // namespace
}  // namespace specula::codec
