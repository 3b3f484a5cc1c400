#include "specula/codec/uplift.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <random>

#include "quadrature_support.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;

const WavelengthGrid& grid31() {
  static const WavelengthGrid g = WavelengthGrid::range(400, 700, 10);
  return g;
}

// Dynamic-size helpers (GCC 12 misreads fixed 3-vectors under AVX as out-of-bounds reads).
double max_abs(const Eigen::VectorXd& v) { return v.cwiseAbs().maxCoeff(); }

Eigen::Matrix<double, 3, Eigen::Dynamic> weights31() { return rgb_weights(grid31(), illuminant("D65", grid31())); }

Eigen::MatrixXd second_differences(Eigen::Index b) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(b - 2, b);
  for (Eigen::Index r = 0; r + 2 < b; ++r) d.row(r).segment(r, 3) << 1, -2, 1;
  return d;
}

// Smooth, positive spectra: a base plus a broad Gaussian bump.
Eigen::VectorXd smooth_spectrum(double base, double height, double centre, double width) {
  Eigen::VectorXd x(31);
  for (Eigen::Index k = 0; k < 31; ++k) {
    const double t = (grid31()[std::size_t(k)] - centre) / width;
    x[k] = base + height * std::exp(-t * t);
  }
  return x;
}

// The alpha -> 0 limit of eq A.3, solved independently: minimise |D x|^2 subject to A x = c (KKT system).
Eigen::VectorXd min_curvature_exact(const Eigen::Matrix<double, 3, Eigen::Dynamic>& a, const Eigen::VectorXd& c) {
  const Eigen::MatrixXd d = second_differences(31);
  Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(34, 34);
  kkt.topLeftCorner(31, 31) = 2 * d.transpose() * d;
  kkt.topRightCorner(31, 3) = a.transpose();
  kkt.bottomLeftCorner(3, 31) = a;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(34);
  rhs.tail(3) = c;
  return kkt.fullPivLu().solve(rhs).head(31);
}

// A spectrum linear in wavelength has no second differences, so if it also matches the RGB it is the exact
// minimiser of eq A.3 for every alpha (and the system has full rank, so the only one).
// Appendix A on an irregular grid (spacings 3 to 20 nm): the uplifted spectrum has the target sRGB (adapted from the
// light's white to sRGB's as rgb_weights does) by the trapezoid rule on the actual band centres, and, interpolated
// linearly between its bands and integrated on every nm of the CMF table, within that rule's error bound. Weights
// built as if the bands were evenly spaced give a spectrum that misses the target.
TEST(Uplift, OnAnIrregularGridTheSpectrumHasTheTargetRgbByDirectIntegral) {
  const WavelengthGrid grid = test::irregular_grid();
  const std::size_t b = grid.size();
  const test::Spectrum light = [](double l) { return 0.8 + 0.4 * (l - 400) / 300 + 0.1 * std::sin(l / 35); };
  Eigen::VectorXd light_g(static_cast<Eigen::Index>(b)), uniform_w(static_cast<Eigen::Index>(b));
  for (std::size_t i = 0; i < b; ++i) light_g[Eigen::Index(i)] = light(grid[i]);
  const Eigen::Vector3d target(0.55, 0.3, 0.12);
  const Eigen::Matrix3d m = xyz_to_linear_srgb();
  const Eigen::Vector3d srgb_white = m.inverse() * Eigen::Vector3d::Ones();
  // Integrals 0-2: cmf * light * x interpolated between bands; 3-5: cmf * light.
  const auto rgb_of = [&](const std::vector<double>& i) {
    const Eigen::Vector3d xyz(i[0] / i[4], i[1] / i[4], i[2] / i[4]), white(i[3] / i[4], 1, i[5] / i[4]);
    return Eigen::VectorXd(m * bradford_adaptation(white, srgb_white) * xyz);
  };
  const auto direct_rgb = [&](const Eigen::VectorXd& x) {
    const test::Spectrum interpolated = [&](double l) {
      return sample_tabulated(grid.values(), std::span<const double>(x.data(), b), WavelengthGrid({l}))[0];
    };
    std::vector<test::Spectrum> f;
    for (int c = 0; c < 3; ++c)
      f.push_back([&, c](double l) { return test::cmf_at(c, l) * light(l) * interpolated(l); });
    for (int c = 0; c < 3; ++c) f.push_back([&, c](double l) { return test::cmf_at(c, l) * light(l); });
    return test::propagate(f, grid, rgb_of);
  };

  Eigen::VectorXd x(static_cast<Eigen::Index>(b));
  const Uplift up(rgb_weights(grid, light_g), kDefaultUpliftAlpha);
  EXPECT_FALSE(up.clamped(target, x));
  const Eigen::VectorXd rgb = target;
  test::expect_integrals(rgb, direct_rgb(x), 1e-6);

  // The uniform-step mistake: weights whose quadrature treats every band as 10 nm wide. Its spectrum misses.
  const double step = (grid.back() - grid.front()) / double(b - 1);
  uniform_w.setConstant(step);
  uniform_w[0] = uniform_w[Eigen::Index(b - 1)] = step / 2;
  const Eigen::MatrixX3d bar = cmf(grid);
  Eigen::Matrix<double, 3, Eigen::Dynamic> xyz_w = bar.transpose() * uniform_w.cwiseProduct(light_g).asDiagonal();
  xyz_w /= xyz_w.row(1).sum();
  const Uplift wrong(m * bradford_adaptation(xyz_w.rowwise().sum(), srgb_white) * xyz_w, kDefaultUpliftAlpha);
  wrong.clamped(target, x);
  EXPECT_GT((direct_rgb(x).nodes - rgb).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(Uplift, LinearSpectrumIsRecoveredForEveryAlpha) {
  const auto a = weights31();
  Eigen::VectorXd lin(31);
  for (Eigen::Index k = 0; k < 31; ++k) lin[k] = 0.1 + 0.02 * double(k);
  const Eigen::Vector3d rgb = a * lin;
  for (double alpha : {1e-4, 1e-2, 1.0, 100.0}) {
    const Uplift up(a, alpha);
    Eigen::VectorXd x(31);
    EXPECT_FALSE(up.clamped(rgb, x));
    EXPECT_LT((x - lin).cwiseAbs().maxCoeff(), 1e-9) << alpha;
    EXPECT_FALSE(up.nonnegative(rgb, x));
    EXPECT_LT((x - lin).cwiseAbs().maxCoeff(), 1e-9) << alpha;
  }
}

TEST(Uplift, FeasibleRgbIsReproducedAndTendsToTheMinimumCurvatureSolution) {
  const auto a = weights31();
  const Uplift up(a, kDefaultUpliftAlpha);
  for (const Eigen::VectorXd& s : {smooth_spectrum(0.1, 0.6, 550, 50), smooth_spectrum(0.05, 0.8, 620, 40),
                                   smooth_spectrum(0.3, 0.4, 460, 70), smooth_spectrum(0.02, 3.0, 500, 80)}) {
    const Eigen::VectorXd rgb = a * s;
    Eigen::VectorXd x(31);
    up.nonnegative(rgb, x);
    EXPECT_LE(max_abs(a * x - rgb), 1e-6 * max_abs(rgb));
    const Eigen::VectorXd exact = min_curvature_exact(a, rgb);
    if (exact.minCoeff() >= 0) {
      EXPECT_LT((x - exact).cwiseAbs().maxCoeff(), 1e-4 * exact.cwiseAbs().maxCoeff());
    }
  }
}

// Tikhonov: as alpha grows the solution's second differences shrink and its RGB error grows, monotonically.
TEST(Uplift, SmoothnessGrowsWithAlpha) {
  const auto a = weights31();
  const Eigen::MatrixXd d = second_differences(31);
  const Eigen::Vector3d rgb(0.6, 0.3, 0.1);
  double last_curv = 1e300, last_err = -1;
  for (double alpha : {1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0}) {
    const Uplift up(a, alpha);
    Eigen::VectorXd x(31);
    up.solve(rgb, x);
    const double curv = (d * x).norm(), err = (a * x - rgb).norm();
    EXPECT_LT(curv, last_curv) << alpha;
    EXPECT_GE(err, last_err) << alpha;
    last_curv = curv;
    last_err = err;
  }
  EXPECT_GT(last_err, 1e-3);  // at alpha = 10 smoothness wins over fidelity
}

TEST(Uplift, ClampingIsAppendixA) {
  const auto a = weights31();
  const Uplift up(a, 1e-2);
  const Eigen::Vector3d blue(0.02, 0.03, 0.9);
  Eigen::VectorXd raw(31), x(31);
  up.solve(blue, raw);
  ASSERT_LT(raw.minCoeff(), 0.0);  // a saturated blue needs negative light somewhere
  EXPECT_TRUE(up.clamped(blue, x));
  EXPECT_EQ(x, raw.cwiseMax(0.0));
}

// The bounded solution satisfies the KKT conditions of min |M x - b|^2, x >= 0, and beats clamping.
TEST(Uplift, NonNegativeIsTheBoundedLeastSquaresOptimum) {
  const auto a = weights31();
  const Uplift up(a, 1e-2);
  const Eigen::MatrixXd& m = up.system();
  for (const Eigen::Vector3d& rgb :
       {Eigen::Vector3d(0.02, 0.03, 0.9), Eigen::Vector3d(0.9, 0.05, 0.02), Eigen::Vector3d(0.05, 0.8, 0.05)}) {
    Eigen::VectorXd x(31), xc(31);
    EXPECT_TRUE(up.nonnegative(rgb, x));
    up.clamped(rgb, xc);
    EXPECT_GE(x.minCoeff(), 0.0);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(m.rows());
    b.head(3) = rgb;
    const Eigen::VectorXd grad = m.transpose() * (m * x - b);
    const double tol = 1e-9 * (m.transpose() * b).cwiseAbs().maxCoeff();
    for (Eigen::Index k = 0; k < 31; ++k) {
      if (x[k] > 0)
        EXPECT_NEAR(grad[k], 0.0, tol) << k;
      else
        EXPECT_GE(grad[k], -tol) << k;
    }
    EXPECT_LE((m * x - b).norm(), (m * xc - b).norm() + 1e-15);
  }
}

// Reusing active sets gives the same optimum as solving afresh, over a sweep of saturated colours where
// neighbours share active sets (hits) and some do not (misses).
TEST(Uplift, ActiveSetCacheGivesTheSameOptimum) {
  const auto a = weights31();
  const Uplift up(a, 1e-2);
  UpliftCache cache;
  int constrained = 0;
  for (int i = 0; i < 600; ++i) {
    const double h = 6.0 * i / 600, f = h - std::floor(h);
    Eigen::Vector3d rgb;
    switch (int(h)) {  // hue wheel at full saturation, with a little white
      case 0:
        rgb << 1, f, 0;
        break;
      case 1:
        rgb << 1 - f, 1, 0;
        break;
      case 2:
        rgb << 0, 1, f;
        break;
      case 3:
        rgb << 0, 1 - f, 1;
        break;
      case 4:
        rgb << f, 0, 1;
        break;
      default:
        rgb << 1, 0, 1 - f;
        break;
    }
    rgb = (rgb.array() * 0.9 + 0.02).matrix() * (0.5 + 0.001 * i);
    Eigen::VectorXd x(31), y(31);
    const bool c1 = up.nonnegative(rgb, x, &cache);
    const bool c2 = up.nonnegative(rgb, y);
    ASSERT_EQ(c1, c2) << i;
    constrained += c1;
    ASSERT_LT((x - y).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, y.cwiseAbs().maxCoeff())) << i;
  }
  EXPECT_GT(constrained, 100);
  EXPECT_GT(cache.hits(), cache.misses());
  EXPECT_GT(cache.misses(), 1u);
}

TEST(Uplift, BadParametersAreUsageErrors) {
  EXPECT_THROW(Uplift(weights31(), -1), UsageError);
  EXPECT_THROW(Uplift(weights31(), std::nan("")), UsageError);
  EXPECT_THROW(Uplift(weights31(), 0.0), UsageError);  // 31 unknowns, 3 equations: needs the regulariser
  EXPECT_THROW(Uplift(Eigen::Matrix<double, 3, 2>::Ones(), 1.0), UsageError);
}

// A whole MERL BRDF: cells made from smooth spectra come back to the same RGB (through the export path),
// cells without data stay without data.
TEST(Uplift, MerlBrdfRoundTripsThroughExport) {
  const auto a = weights31();
  MerlBrdf rgb;
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::size_t> cells;
  for (std::size_t cell = 0; cell < N; cell += 997) {
    const Eigen::VectorXd s = smooth_spectrum(0.05 + 0.2 * u(rng), 2 * u(rng), 450 + 200 * u(rng), 40 + 60 * u(rng));
    const Eigen::VectorXd c = a * s;
    if (c.minCoeff() <= 0) continue;  // outside the sRGB gamut: a MERL file cannot hold it
    rgb.set(cell, c);
    cells.push_back(cell);
  }
  const Uplift up(a, kDefaultUpliftAlpha);
  UpliftReport report;
  const store::Grid g = uplift_merl(rgb, grid31(), up, UpliftMethod::nonnegative, &report);
  EXPECT_EQ(report.cells, cells.size());
  EXPECT_LE(report.max_rgb_error, 1e-6);
  EXPECT_EQ(g.bands(), 31u);
  EXPECT_EQ(g.brdf[1], -1.0f);
  EXPECT_EQ(g.brdf[30 * N + 1], -1.0f);
  const RgbExport back = grid_to_merl(g, a);
  EXPECT_EQ(back.clamped, 0u);
  for (std::size_t cell : cells) {
    // Relative to the cell's largest channel: the grid holds float32 (about 6e-8 of each band).
    const double scale = std::max({rgb.value(0, cell), rgb.value(1, cell), rgb.value(2, cell)});
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(back.brdf.value(c, cell), rgb.value(c, cell), 1e-6 * scale) << cell;
  }
  EXPECT_FALSE(back.brdf.has_data(1));
  EXPECT_THROW(uplift_merl(rgb, WavelengthGrid::range(400, 700, 20), up, UpliftMethod::clamp), UsageError);
}

// An image of saturated hues (many pixels need the bound) whose rows repeat colours, so the per-row caches hit.
std::vector<float> hue_image(std::size_t w, std::size_t h) {
  std::vector<float> rgb;
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x) {
      const double t = double((x + 3 * y) % 48) / 48, f = 6 * t - std::floor(6 * t);
      const double c[6][3] = {{1, f, 0}, {1 - f, 1, 0}, {0, 1, f}, {0, 1 - f, 1}, {f, 0, 1}, {1, 0, 1 - f}};
      for (int k = 0; k < 3; ++k) rgb.push_back(float((0.9 * c[int(6 * t)][k] + 0.02) * (0.5 + 0.01 * double(y))));
    }
  return rgb;
}

// Every pixel is the solution Uplift gives it alone (no cache), the count that of the pixels it constrained, and
// the output the same for 1 and 2 threads.
TEST(Uplift, ImagePixelsAreThoseOfTheSingleSolveWhateverTheThreadCount) {
  const std::size_t w = 37, h = 11, b = 31;
  const std::vector<float> rgb = hue_image(w, h);
  const Uplift up(rgb_weights(grid31(), Eigen::VectorXd::Ones(31)), kDefaultUpliftAlpha);
  const int saved = omp_get_max_threads();
  for (const UpliftMethod method : {UpliftMethod::clamp, UpliftMethod::nonnegative}) {
    std::vector<float> one(w * h * b, -1), two(w * h * b, -2);
    omp_set_num_threads(1);
    const std::size_t c1 = uplift_image(rgb, w, h, up, method, one);
    omp_set_num_threads(2);
    const std::size_t c2 = uplift_image(rgb, w, h, up, method, two);
    omp_set_num_threads(saved);
    EXPECT_EQ(one, two);
    EXPECT_EQ(c1, c2);
    std::size_t constrained = 0;
    Eigen::VectorXd x(31);
    for (std::size_t p = 0; p < w * h; ++p) {
      const Eigen::Vector3d c(rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]);
      constrained += method == UpliftMethod::clamp ? up.clamped(c, x) : up.nonnegative(c, x);
      for (std::size_t k = 0; k < b; ++k)
        ASSERT_NEAR(one[p * b + k], x[Eigen::Index(k)], 1e-6 * std::max(1.0, x.cwiseAbs().maxCoeff())) << p << " " << k;
    }
    EXPECT_EQ(c1, constrained);
    EXPECT_GT(constrained, w * h / 4);
  }
}

TEST(Uplift, ImageWithANegativeChannelOrWrongSizesIsRejected) {
  const std::size_t w = 5, h = 3;
  std::vector<float> rgb(3 * w * h, 0.5f), out(31 * w * h);
  const Uplift up(rgb_weights(grid31(), Eigen::VectorXd::Ones(31)), kDefaultUpliftAlpha);
  rgb[3 * (2 * w + 4) + 1] = -0.25f;
  EXPECT_EQ(test::input_error_text([&] { uplift_image(rgb, w, h, up, UpliftMethod::clamp, out); }),
            "pixel (4, 2) has a negative channel; radiance must be non-negative");
  rgb[3 * (2 * w + 4) + 1] = 0.25f;
  EXPECT_THROW(uplift_image(rgb, w, h + 1, up, UpliftMethod::clamp, out), UsageError);
  EXPECT_THROW(uplift_image(rgb, w, h, up, UpliftMethod::clamp, std::span<float>(out).first(10)), UsageError);
  EXPECT_EQ(uplift_image(rgb, w, h, up, UpliftMethod::nonnegative, out), 0u);
}

}  // namespace
}  // namespace specula::codec

namespace specula::codec {
namespace {

// Saturated hues in every 7th cell, repeating so the active-set caches hit: the grid is bit-identical for 1 and
// 2 threads (caches live per block of cells, not per thread).
TEST(Uplift, MerlGridDoesNotDependOnTheThreadCount) {
  const std::vector<float> hues = hue_image(48, 8);
  MerlBrdf rgb;
  for (std::size_t cell = 0, i = 0; cell < brdf::kMerlCells; cell += 7, i = (i + 1) % (48 * 8))
    rgb.set(cell, Eigen::Vector3d(hues[3 * i], hues[3 * i + 1], hues[3 * i + 2]));
  const Uplift up(rgb_weights(grid31(), Eigen::VectorXd::Ones(31)), kDefaultUpliftAlpha);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  UpliftReport r1, r2;
  const store::Grid one = uplift_merl(rgb, grid31(), up, UpliftMethod::nonnegative, &r1);
  omp_set_num_threads(2);
  const store::Grid two = uplift_merl(rgb, grid31(), up, UpliftMethod::nonnegative, &r2);
  omp_set_num_threads(saved);
  EXPECT_GT(r1.constrained, 0u);
  EXPECT_EQ(r1.constrained, r2.constrained);
  EXPECT_EQ(r1.max_rgb_error, r2.max_rgb_error);
  std::size_t diff = 0, first = 0;
  for (std::size_t i = 0; i < one.brdf.size(); ++i)
    if (one.brdf[i] != two.brdf[i] && diff++ == 0) first = i;
  EXPECT_EQ(diff, 0u) << "first at value " << first << " (cell " << first % brdf::kMerlCells << "): " << one.brdf[first]
                      << " vs " << two.brdf[first];
}

}  // namespace
}  // namespace specula::codec
