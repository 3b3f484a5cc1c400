#include "specula/core/brdf_resample.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/merl_cells.h"
#include "test_support.h"

namespace specula::brdf {
namespace {

using std::numbers::pi;

constexpr Mapping kAll[] = {Mapping::standard, Mapping::marschner, Mapping::halfdiff};

StdAngles random_angles(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  return {t(rng), p(rng), t(rng), p(rng)};
}

struct Samples {
  std::vector<double> angles;
  std::vector<float> values;
  std::size_t size() const { return angles.size() / 4; }
  StdAngles at(std::size_t i) const { return {angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]}; }
};

// n random samples with `bands` values that vary smoothly with the configuration.
Samples random_samples(std::size_t n, std::size_t bands, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Samples s;
  for (std::size_t i = 0; i < n; ++i) {
    const auto a = random_angles(rng);
    s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    for (std::size_t q = 0; q < bands; ++q)
      s.values.push_back(
          float(1 + std::cos(a.theta_i + 0.1 * double(q)) * std::cos(a.theta_o) + 0.1 * std::cos(a.phi_o - a.phi_i)));
  }
  return s;
}

TEST(Resampler, NeighboursEqualABruteForceSearch) {
  const Samples s = random_samples(4000, 1, 5);
  std::mt19937_64 rng(6);
  for (const Mapping m : kAll) {
    const Resampler r(s.angles, s.values, 1, {.mapping = m, .k = 9});
    Neighbours nb;
    for (int q = 0; q < 60; ++q) {
      const auto at = random_angles(rng);
      r.neighbours(at, nb);
      std::vector<std::pair<double, std::uint32_t>> all;
      const Eigen::Vector3d p = map_angles(m, at);
      for (std::size_t i = 0; i < s.size(); ++i)
        all.push_back({(map_angles(m, s.at(i)) - p).squaredNorm(), std::uint32_t(i)});
      std::sort(all.begin(), all.end());
      ASSERT_EQ(nb.index.size(), 9u);
      for (std::size_t j = 0; j < 9; ++j) {
        // Distances agree to float rounding; indices too unless two distances are that close.
        EXPECT_NEAR(nb.dist2[j], all[j].first, 1e-6 * (1 + all[j].first)) << mapping_name(m);
        const bool tie = (j > 0 && all[j].first - all[j - 1].first < 1e-5) || all[j + 1].first - all[j].first < 1e-5;
        if (!tie) {
          EXPECT_EQ(nb.index[j], all[j].second) << mapping_name(m) << " neighbour " << j;
        }
      }
      // The gap is the configuration distance to the nearest (to it or its reciprocal configuration, as the mapping).
      const IsoAngles a = iso_angles(at), b = iso_angles(s.at(nb.index[0]));
      EXPECT_NEAR(nb.gap, config_distance(a, b, mapping_is_reciprocal(m)), 1e-3);
    }
  }
}

// Millions of samples are cut into slabs with a tree each, searched outwards from the query's own slab.
TEST(Resampler, NeighboursOfManySamplesInSlabsEqualABruteForceSearch) {
  const std::size_t n = 3200000;
  std::mt19937_64 rng(9);
  std::vector<double> angles(4 * n);
  std::vector<float> values(n, 0.0f);
  std::vector<Eigen::Vector3f> points(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto a = random_angles(rng);
    std::copy_n(&a.theta_i, 4, angles.begin() + std::ptrdiff_t(4 * i));
    points[i] = map_angles(Mapping::standard, a).cast<float>();
  }
  const Resampler r(angles, values, 1, {.k = 40});
  Neighbours nb;
  std::vector<float> d2(n);
  for (int q = 0; q < 60; ++q) {
    // Queries along the widest axis (phi_d) from end to end, so that many lie near a cut between slabs.
    const StdAngles at{0.3 + 0.01 * q, 0.0, 1.1 - 0.012 * q, pi * (q + 0.5) / 60};
    r.neighbours(at, nb);
    const Eigen::Vector3f p = map_angles(Mapping::standard, at).cast<float>();
    for (std::size_t i = 0; i < n; ++i) d2[i] = (points[i] - p).squaredNorm();
    std::vector<float> sorted = d2;
    std::nth_element(sorted.begin(), sorted.begin() + 39, sorted.end());
    const float kth = sorted[39];
    ASSERT_EQ(nb.index.size(), 40u);
    EXPECT_NEAR(nb.dist2.back(), kth, 1e-6f * kth);
    for (std::size_t j = 0; j < 40; ++j) EXPECT_LE(d2[nb.index[j]], kth * (1 + 1e-6f)) << q;
    EXPECT_TRUE(std::is_sorted(nb.dist2.begin(), nb.dist2.end()));
  }
}

TEST(Resampler, ShepardAndMeanWeightsInClosedForm) {
  std::vector<float> w(3);
  neighbour_weights(Weights::mean, 1, std::vector<float>{1, 4, 9}, w);
  for (const float x : w) EXPECT_FLOAT_EQ(x, 1.0f / 3);
  // p = 1: 1/d = 1, 1/2, 1/3 over their sum 11/6.
  neighbour_weights(Weights::shepard, 1, std::vector<float>{1, 4, 9}, w);
  EXPECT_FLOAT_EQ(w[0], 6.0f / 11);
  EXPECT_FLOAT_EQ(w[1], 3.0f / 11);
  EXPECT_FLOAT_EQ(w[2], 2.0f / 11);
  // p = 2: 1/d^2 = 1, 1/4, 1/9 over 49/36.
  neighbour_weights(Weights::shepard, 2, std::vector<float>{1, 4, 9}, w);
  EXPECT_FLOAT_EQ(w[1], 9.0f / 49);
  // Samples at distance 0 share everything.
  neighbour_weights(Weights::shepard, 1, std::vector<float>{0, 0, 9}, w);
  EXPECT_EQ(w, (std::vector<float>{0.5f, 0.5f, 0.0f}));
  // p = 0 is the mean.
  neighbour_weights(Weights::shepard, 0, std::vector<float>{1, 4, 9}, w);
  EXPECT_FLOAT_EQ(w[2], 1.0f / 3);
}

TEST(Resampler, RenkaWeightsInClosedForm) {
  std::vector<float> w(3);
  // R = 4: (1/d - 1/R)^2 = 9/16, 1/16, 1/144 over their sum 91/144.
  neighbour_weights(Weights::renka, 1, std::vector<float>{1, 4, 9}, w, 16);
  EXPECT_FLOAT_EQ(w[0], 81.0f / 91);
  EXPECT_FLOAT_EQ(w[1], 9.0f / 91);
  EXPECT_FLOAT_EQ(w[2], 1.0f / 91);
  // No (k+1)-th sample (R infinite): 1/d^2 = 1, 1/4, 1/9 over 49/36; the power plays no part.
  neighbour_weights(Weights::renka, 7, std::vector<float>{1, 4, 9}, w);
  EXPECT_FLOAT_EQ(w[0], 36.0f / 49);
  EXPECT_FLOAT_EQ(w[2], 4.0f / 49);
  // A neighbour at the reach has weight 0; all of them there: the mean.
  neighbour_weights(Weights::renka, 1, std::vector<float>{1, 4, 4}, w, 4);
  EXPECT_EQ(w, (std::vector<float>{1.0f, 0.0f, 0.0f}));
  neighbour_weights(Weights::renka, 1, std::vector<float>{4, 4, 4}, w, 4);
  for (const float x : w) EXPECT_FLOAT_EQ(x, 1.0f / 3);
  // A sample at distance 0 takes everything.
  neighbour_weights(Weights::renka, 1, std::vector<float>{0, 1, 4}, w, 9);
  EXPECT_EQ(w, (std::vector<float>{1.0f, 0.0f, 0.0f}));
}

// Renka's weights computed here from every sample's distance (no tree, no shared code): predict must equal that,
// and along a path of small steps the estimate must not jump where the neighbour set changes, as Shepard's does.
TEST(Resampler, RenkaEqualsABruteForceModifiedShepardAndIsContinuous) {
  const Samples s = random_samples(2000, 1, 21);
  const std::size_t k = 8;
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < s.size(); ++i) points.push_back(map_angles(Mapping::standard, iso_angles(s.at(i))));
  auto brute = [&](const StdAngles& at) {
    const Eigen::Vector3d p = map_angles(Mapping::standard, iso_angles(at));
    std::vector<std::pair<double, std::size_t>> d;
    for (std::size_t i = 0; i < points.size(); ++i) d.emplace_back((points[i] - p).norm(), i);
    std::partial_sort(d.begin(), d.begin() + std::ptrdiff_t(k + 1), d.end());
    const double r = d[k].first;
    double num = 0, den = 0;
    for (std::size_t j = 0; j < k; ++j) {
      const double w = std::pow(std::max(0.0, r - d[j].first) / (r * d[j].first), 2);
      num += w * s.values[d[j].second];
      den += w;
    }
    return num / den;
  };
  const Resampler renka(s.angles, s.values, 1, {.k = k, .weights = Weights::renka, .max_gap = 10});
  const Resampler shepard(s.angles, s.values, 1, {.k = k, .weights = Weights::shepard, .max_gap = 10});
  std::vector<float> out(1);
  double prev_r = 0, prev_s = 0, jump_r = 0, jump_s = 0;
  const int steps = 20000;
  for (int i = 0; i <= steps; ++i) {
    const StdAngles at{0.3 + 0.9 * i / steps, 0.0, 0.7, 2.0 - 1.2 * i / steps};
    ASSERT_TRUE(renka.predict(at, out));
    const double r = out[0];
    if (i % 500 == 0) {
      EXPECT_NEAR(r, brute(at), 1e-5 * std::abs(r)) << i;
    }
    ASSERT_TRUE(shepard.predict(at, out));
    if (i > 0) {
      jump_r = std::max(jump_r, std::abs(r - prev_r));
      jump_s = std::max(jump_s, std::abs(out[0] - prev_s));
    }
    prev_r = r;
    prev_s = out[0];
  }
  // Steps of 5e-5 rad: a continuous estimate moves by its gradient times that; Shepard's jumps by a share of
  // the values' spread (about 1) where one neighbour swaps for another.
  EXPECT_LT(jump_r, 2e-3);
  EXPECT_GT(jump_s, 5 * jump_r);
  // The streamed grid keeps k entries per cell while Renka's search finds k + 1: still predict at the centres.
  std::vector<float> grid(kMerlCells);
  renka.fill_grid(grid);
  for (std::size_t c = 0; c < kMerlCells; c += 4099) {
    const brdf::MerlCell cell = brdf::merl_cell(c);
    if (!brdf::merl_cell_valid(cell)) continue;
    ASSERT_TRUE(renka.predict(brdf::std_angles(brdf::merl_cell_centre(cell)), out));
    ASSERT_EQ(grid[c], out[0]) << c;
  }
}

TEST(Resampler, SamplesAtCellCentresAreReproducedExactlyWithOneNeighbour) {
  Samples s;
  std::vector<std::size_t> cells;
  for (std::size_t c = 0; c < kMerlCells; c += 97) {
    const brdf::MerlCell cell = brdf::merl_cell(c);
    if (!brdf::merl_cell_valid(cell)) continue;
    const StdAngles a = brdf::std_angles(brdf::merl_cell_centre(cell));
    s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    s.values.push_back(float(c) * 0.5f + 0.1f);
    s.values.push_back(float(c) * 0.25f + 0.3f);
    cells.push_back(c);
  }
  for (const Weights w : {Weights::mean, Weights::shepard, Weights::renka}) {
    const Resampler r(s.angles, s.values, 2, {.mapping = Mapping::standard, .k = 1, .weights = w, .max_gap = 10});
    std::vector<float> grid(2 * kMerlCells);
    r.fill_grid(grid);
    for (std::size_t j = 0; j < cells.size(); ++j) {
      ASSERT_EQ(grid[cells[j]], s.values[2 * j]) << cells[j];
      ASSERT_EQ(grid[kMerlCells + cells[j]], s.values[2 * j + 1]) << cells[j];
    }
  }
  // M_m and M_h send reciprocal configurations to one point, and some cell centres are (nearly) reciprocal to
  // others: there the cell gets the value of a sample whose mapped point is the same in float precision.
  for (const Mapping m : {Mapping::marschner, Mapping::halfdiff}) {
    const Resampler r(s.angles, s.values, 2, {.mapping = m, .k = 1, .max_gap = 10});
    std::vector<float> grid(2 * kMerlCells);
    r.fill_grid(grid);
    std::size_t own = 0;
    for (std::size_t j = 0; j < cells.size(); ++j) {
      if (grid[cells[j]] == s.values[2 * j]) {
        ++own;
        ASSERT_EQ(grid[kMerlCells + cells[j]], s.values[2 * j + 1]);
        continue;
      }
      const auto other =
          std::size_t(std::find(s.values.begin(), s.values.end(), grid[cells[j]]) - s.values.begin()) / 2;
      ASSERT_LT(other, cells.size()) << mapping_name(m) << " cell " << cells[j];
      ASSERT_EQ((map_angles(m, s.at(other)).cast<float>() - map_angles(m, s.at(j)).cast<float>()).norm(), 0.0f)
          << mapping_name(m) << " cell " << cells[j];
    }
    EXPECT_GT(own, cells.size() * 99 / 100) << mapping_name(m);
  }
  // Shepard with more neighbours still returns a sample that sits exactly on the query.
  const Resampler r(s.angles, s.values, 2, {.k = 8, .weights = Weights::shepard});
  std::vector<float> out(2);
  ASSERT_TRUE(r.predict(s.at(5), out));
  EXPECT_EQ(out[0], s.values[10]);
}

// Shepard weights are a convex combination: a constant is reproduced exactly, and a field linear in the
// mapped coordinates is reproduced to within its gradient times the distance of the farthest neighbour used.
TEST(Resampler, ShepardReproducesConstantsAndLinearFieldsToInterpolationAccuracy) {
  std::mt19937_64 rng(3);
  const Eigen::Vector3d grad(0.3, -0.2, 0.1);
  for (const Mapping m : kAll) {
    Samples s;
    for (int i = 0; i < 20000; ++i) {
      const auto a = random_angles(rng);
      s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
      s.values.push_back(2.5f);
      s.values.push_back(float(1 + grad.dot(map_angles(m, a))));
    }
    const Resampler r(s.angles, s.values, 2, {.mapping = m, .k = 16, .weights = Weights::shepard, .power = 2});
    std::vector<float> out(2);
    Neighbours nb;
    std::uniform_real_distribution<double> t(0.2, 1.2), p(0.3, 2.8);
    double worst = 0, mean_err = 0;
    for (int q = 0; q < 300; ++q) {
      const StdAngles at{t(rng), 0.0, t(rng), p(rng)};
      ASSERT_TRUE(r.predict(at, out)) << mapping_name(m);
      EXPECT_NEAR(out[0], 2.5f, 2e-6);
      r.neighbours(at, nb);
      const double reach = std::sqrt(double(nb.dist2.back()));
      const double err = std::abs(out[1] - (1 + grad.dot(map_angles(m, at))));
      EXPECT_LE(err, grad.norm() * reach + 1e-5) << mapping_name(m);
      worst = std::max(worst, reach);
      mean_err += err / 300;
    }
    // And the interpolation is far better than that bound on average (a sign that the weights are inverse
    // distances and not, say, uniform over a biased neighbourhood).
    EXPECT_LT(mean_err, 0.5 * grad.norm() * worst) << mapping_name(m);
  }
}

// Samples on a lattice of step 1/16 rad and queries between its points: squared distances are exact in float and
// tie often, also at the k-th neighbour. Every search takes the k smallest by (distance, sample index).
TEST(Resampler, NeighboursTieToTheLowerSampleIndexOneQueryAtATimeOrARowAtATime) {
  std::vector<double> angles;
  std::vector<Eigen::Vector3f> points;
  for (int a = 1; a <= 24; ++a)
    for (int b = 1; b <= 24; ++b)
      for (int c = 0; c <= 50; ++c) {
        angles.insert(angles.end(), {a / 16.0, 0.0, b / 16.0, c / 16.0});
        points.push_back(Eigen::Vector3f(float(a) / 16, float(b) / 16, float(c) / 16));
      }
  const std::vector<float> values(points.size(), 0.0f);
  const MemorySamples src(angles, values, 1);
  const SampleTree tree(src, Mapping::standard);
  std::size_t ties = 0, bounded = 0;
  for (const std::size_t k : {1, 9, 10, 27}) {
    for (int row = 0; row < 12; ++row) {
      // Sixteen queries along phi_d, half a step off the lattice in theta_i and theta_o.
      std::vector<IsoAngles> at;
      for (int t = 0; t < 16; ++t)
        at.push_back({(2 * row + 3) / 32.0, (4 * row + 5) / 32.0, (2 * (3 * row + t) + 1 + (t % 2)) / 32.0});
      std::vector<Neighbours> each(at.size());
      tree.nearest_each(at, k, each);
      for (std::size_t i = 0; i < at.size(); ++i) {
        const Eigen::Vector3f q(float(at[i].theta_i), float(at[i].theta_o), float(at[i].phi_d));
        std::vector<std::pair<float, std::uint32_t>> brute;
        for (std::size_t j = 0; j < points.size(); ++j)
          brute.push_back({(points[j] - q).squaredNorm(), std::uint32_t(j)});
        std::sort(brute.begin(), brute.end());
        ties += brute[k].first == brute[k - 1].first;
        std::vector<std::pair<float, std::uint32_t>> want(brute.begin(), brute.begin() + std::ptrdiff_t(k));
        Neighbours one;
        tree.nearest(at[i], k, one);
        std::vector<std::pair<float, std::uint32_t>> got_one, got_each;
        for (std::size_t j = 0; j < one.index.size(); ++j) got_one.push_back({one.dist2[j], one.index[j]});
        for (std::size_t j = 0; j < each[i].index.size(); ++j) got_each.push_back({each[i].dist2[j], each[i].index[j]});
        EXPECT_EQ(got_one, want) << "k " << k << " query " << i;  // nearest first already
        std::sort(got_each.begin(), got_each.end());
        EXPECT_EQ(got_each, want) << "k " << k << " query " << i;
        EXPECT_EQ(each[i].gap, one.gap);
        // With a cap the gap may be a bound, but it falls on the same side of the cap as the exact one.
        std::vector<Neighbours> capped(1);
        tree.nearest_each({&at[i], 1}, k, capped, false, 0.05);
        EXPECT_GE(capped[0].gap, one.gap - 1e-7);
        EXPECT_TRUE(capped[0].gap == one.gap || capped[0].gap <= 0.05);
        EXPECT_EQ(capped[0].gap <= 0.05, one.gap <= 0.05);
        bounded += capped[0].gap != one.gap;
      }
    }
  }
  EXPECT_GT(ties, 50u);     // the k-th distance tied with the (k+1)-th this often: the tie rule was exercised
  EXPECT_GT(bounded, 50u);  // and gaps were bounds, not computed
}

// A thread's rows bound the next row's search by the candidates of the row before, held as positions in a tree: a
// row searched in a smaller tree right after one in a larger tree must not read the larger tree's positions.
TEST(Resampler, ARowAfterARowOfAnotherTreeFindsWhatOneQueryAtATimeFinds) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> theta(0.05, 1.5), phi(0, pi);
  const auto samples = [&](int n) {
    std::vector<double> angles;
    for (int i = 0; i < n; ++i) angles.insert(angles.end(), {theta(rng), 0.0, theta(rng), phi(rng)});
    return angles;
  };
  const std::vector<double> large = samples(50000), small = samples(300);
  const std::vector<float> values(large.size() / 4, 0.0f);
  const SampleTree big(MemorySamples(large, values, 1), Mapping::standard);
  const SampleTree few(MemorySamples(small, std::span(values).first(small.size() / 4), 1), Mapping::standard);
  for (int row = 0; row < 6; ++row) {
    std::vector<IsoAngles> at;
    for (int t = 0; t < 16; ++t) at.push_back({0.4 + 0.1 * row, 0.5 + 0.1 * row, 1.0 + 0.01 * t});
    std::vector<Neighbours> each(at.size());
    big.nearest_each(at, 40, each);  // leaves the big tree's candidates as the thread's last row
    few.nearest_each(at, 40, each);
    for (std::size_t i = 0; i < at.size(); ++i) {
      Neighbours one;
      few.nearest(at[i], 40, one);
      std::vector<std::pair<float, std::uint32_t>> a, b;
      for (std::size_t j = 0; j < one.index.size(); ++j) a.push_back({one.dist2[j], one.index[j]});
      for (std::size_t j = 0; j < each[i].index.size(); ++j) b.push_back({each[i].dist2[j], each[i].index[j]});
      std::sort(b.begin(), b.end());
      ASSERT_EQ(a, b) << "row " << row << " query " << i;
    }
  }
}

// A row over an empty region beside a dense one: its ball of candidates would hold thousands, so the row is cut
// down, and every query still gets what searching it alone gives.
TEST(Resampler, ARowBesideADenseClusterFindsWhatOneQueryAtATimeFinds) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> dense(0.05, 0.25), sparse(0.05, 1.5), phi(0, pi);
  std::vector<double> angles;
  for (int i = 0; i < 20000; ++i) angles.insert(angles.end(), {dense(rng), 0.0, dense(rng), phi(rng)});
  for (int i = 0; i < 60; ++i) angles.insert(angles.end(), {sparse(rng), 0.0, sparse(rng), phi(rng)});
  const std::vector<float> values(angles.size() / 4, 0.0f);
  const SampleTree tree(MemorySamples(angles, values, 1), Mapping::standard);
  for (const std::size_t k : {8, 33}) {
    for (int row = 0; row < 20; ++row) {
      std::vector<IsoAngles> at;
      for (int t = 0; t < 16; ++t) at.push_back({0.3 + 0.05 * row, 0.35 + 0.04 * row, pi * (t + 0.5) / 16});
      std::vector<Neighbours> each(at.size());
      tree.nearest_each(at, k, each);
      for (std::size_t i = 0; i < at.size(); ++i) {
        Neighbours one;
        tree.nearest(at[i], k, one);
        std::vector<std::pair<float, std::uint32_t>> a, b;
        for (std::size_t j = 0; j < one.index.size(); ++j) a.push_back({one.dist2[j], one.index[j]});
        for (std::size_t j = 0; j < each[i].index.size(); ++j) b.push_back({each[i].dist2[j], each[i].index[j]});
        std::sort(b.begin(), b.end());
        ASSERT_EQ(a, b) << "k " << k << " row " << row << " query " << i;
        EXPECT_EQ(one.gap, each[i].gap);
      }
    }
  }
}

TEST(Resampler, GridIsPredictAtEveryCellCentreForAnyPassCountAndThreadCount) {
  // 3 bands under every mapping; 18 (other widths of the sums in registers) under the standard one.
  for (const std::size_t bands : {std::size_t(3), std::size_t(18)})
    for (const Mapping m : kAll) {
      if (bands != 3 && m != Mapping::standard) continue;
      const Samples s = random_samples(30000, bands, 7);
      const ResampleOptions o{.mapping = m, .k = 6, .weights = Weights::shepard, .max_gap = 0.12};
      const Resampler r(s.angles, s.values, bands, o);
      std::vector<float> one(bands * kMerlCells);
      const std::size_t valid = r.fill_grid(one);
      EXPECT_GT(valid, 100000u);
      // The streaming grid in many passes over the values (small blocks, few entries per pass) and on one thread.
      const MemorySamples src(s.angles, s.values, bands);
      std::vector<float> many(bands * kMerlCells);
      ResampleOptions small = o;
      small.max_entries = 40009;  // the values (360 KB or more) no longer fit in a pass's neighbour lists (320 KB)
      const int threads = omp_get_max_threads();
      omp_set_num_threads(1);
      const GridStats st = resample_grid(src, small, many);
      omp_set_num_threads(threads);
      EXPECT_GT(st.passes, 5u);
      EXPECT_EQ(st.valid_cells, valid);
      ASSERT_TRUE(one == many) << mapping_name(m);
      // Cell by cell: the same values, a cell's bands together; cells without data left as they were.
      std::vector<float> cells(bands * kMerlCells, 7.0f);
      std::vector<std::uint8_t> flags(kMerlCells, 2);
      EXPECT_EQ(r.fill_cells(cells, flags), valid);
      for (std::size_t c = 0; c < kMerlCells; ++c) {
        ASSERT_EQ(flags[c], one[c] >= 0 ? 1 : 2) << c;
        for (std::size_t q = 0; q < bands; ++q)
          ASSERT_EQ(cells[bands * c + q], one[c] >= 0 ? one[q * kMerlCells + c] : 7.0f) << c;
      }
      // Spot checks against predict at cell centres.
      std::vector<float> out(bands);
      std::size_t checked = 0;
      for (std::size_t c = 0; c < kMerlCells; c += 1013) {
        const brdf::MerlCell cell = brdf::merl_cell(c);
        const bool has = brdf::merl_cell_valid(cell) && r.predict(brdf::std_angles(brdf::merl_cell_centre(cell)), out);
        ASSERT_EQ(one[c] >= 0, has) << c;
        if (!has) continue;
        ++checked;
        for (std::size_t q = 0; q < bands; ++q) ASSERT_EQ(one[q * kMerlCells + c], out[q]) << c;
      }
      EXPECT_GT(checked, 100u);
    }
}

TEST(Resampler, CellsAloneAreTheGridsCellsBitForBit) {
  // A scattered subset (every 7th valid cell) and a few whole rows: in memory and streamed in passes, under weights
  // with and without a reach; every other cell -1 and its gap untouched.
  const Samples s = random_samples(20000, 3, 5);
  const MemorySamples src(s.angles, s.values, 3);
  const auto& valid = merl_valid_cells();
  std::vector<std::uint32_t> subset;
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (i % 7 == 3 || (valid[i] / 180) % 997 == 0) subset.push_back(valid[i]);
  std::vector<std::uint8_t> in(kMerlCells, 0);
  for (const std::uint32_t c : subset) in[c] = 1;
  for (const Weights w : {Weights::shepard, Weights::renka, Weights::loess})
    for (const std::size_t entries : {std::size_t(1) << 24, std::size_t(30011)}) {
      const ResampleOptions o{.k = 8, .weights = w, .max_gap = 0.15, .max_entries = entries};
      const SampleTree tree(src, o.mapping);
      std::vector<float> grid(3 * kMerlCells), part(3 * kMerlCells, 5.0f);
      std::vector<float> gaps(kMerlCells, 9.0f), part_gaps(kMerlCells, 9.0f);
      resample_grid(tree, src, o, grid, gaps);
      resample_cells(tree, src, o, subset, part, part_gaps);
      std::size_t with_data = 0;
      for (std::size_t c = 0; c < kMerlCells; ++c) {
        ASSERT_EQ(part_gaps[c], in[c] ? gaps[c] : 9.0f) << c;
        with_data += in[c] && grid[c] >= 0;
        for (std::size_t q = 0; q < 3; ++q)
          ASSERT_EQ(part[q * kMerlCells + c], in[c] ? grid[q * kMerlCells + c] : -1.0f) << weights_name(w) << " " << c;
      }
      EXPECT_GT(with_data, subset.size() / 2);
    }
  const SampleTree tree(src, Mapping::standard);
  std::vector<float> grid(3 * kMerlCells);
  const std::vector<std::uint32_t> descending = {valid[9], valid[2]}, invalid = {std::uint32_t(kMerlCells - 1)};
  EXPECT_THROW(resample_cells(tree, src, {}, descending, grid), UsageError);
  EXPECT_THROW(resample_cells(tree, src, {}, invalid, grid), UsageError);
}

TEST(Resampler, CellsFarFromEverySampleHaveNoData) {
  // One sample at theta_i = 0.5, theta_o = 0.3, phi_d = pi: a cell has data exactly when it is above the
  // horizon and its centre lies within 0.1 of it in config_distance (tested against brute force in
  // mapping_test); for the reciprocal mappings the swapped configuration counts too.
  const std::vector<double> angles = {0.5, 0.0, 0.3, pi};
  const std::vector<float> values = {1.0f};
  const IsoAngles sample{0.5, 0.3, pi};
  for (const Mapping m : kAll) {
    const Resampler r(angles, values, 1, {.mapping = m, .k = 1, .max_gap = 0.1});
    std::vector<float> grid(kMerlCells);
    const std::size_t valid = r.fill_grid(grid);
    std::size_t expect = 0, swapped = 0;
    for (std::size_t c = 0; c < kMerlCells; ++c) {
      const brdf::MerlCell cell = brdf::merl_cell(c);
      bool ok = false;
      if (brdf::merl_cell_valid(cell)) {
        const IsoAngles a = iso_angles(brdf::std_angles(brdf::merl_cell_centre(cell)));
        const bool direct = config_distance(a, sample, false) <= 0.1;
        const bool either = config_distance(a, sample, true) <= 0.1;
        ok = m == Mapping::standard ? direct : either;
        swapped += either && !direct;
      }
      expect += ok;
      ASSERT_EQ(grid[c] == 1.0f, ok) << mapping_name(m) << " cell " << c;
    }
    EXPECT_EQ(valid, expect);
    EXPECT_GT(swapped, 0u);
    EXPECT_GT(valid, 100u);
    EXPECT_EQ(std::count(grid.begin(), grid.end(), -1.0f), std::ptrdiff_t(kMerlCells - valid));
  }
}

TEST(Resampler, AnInterruptStopsTheGrid) {
  const Samples s = random_samples(5000, 2, 11);
  const MemorySamples src(s.angles, s.values, 2);
  std::vector<float> grid(2 * kMerlCells);
  request_interrupt();
  EXPECT_THROW(resample_grid(src, {}, grid), Interrupted);
  clear_interrupt();
  EXPECT_GT(resample_grid(src, {.k = 4}, grid).valid_cells, 0u);
}

TEST(Resampler, BadOptionsAreRefused) {
  const std::vector<double> angles = {0.5, 0.0, 0.5, pi};
  const std::vector<float> values = {1.0f};
  EXPECT_THROW(Resampler(angles, values, 1, {.k = 0}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 1, {.power = -1}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 1, {.power = std::nan("")}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 1, {.max_gap = 0}), UsageError);
  EXPECT_THROW(Resampler(angles, values, 2, {}), UsageError);
  EXPECT_THROW(Resampler(std::span<const double>(), std::span<const float>(), 1, {}), InputError);
  EXPECT_THROW(parse_weights("median"), UsageError);
  for (const Weights w : {Weights::mean, Weights::shepard, Weights::renka})
    EXPECT_EQ(parse_weights(weights_name(w)), w);
  const Resampler r(angles, values, 1, {});
  std::vector<float> small(10);
  EXPECT_THROW(r.fill_grid(small), UsageError);
}

TEST(ResampleRule, ReadsWhatItWritesAndNamesABadEntry) {
  const ResampleOptions o{
      .mapping = Mapping::halfdiff, .k = 9, .weights = Weights::wendland, .power = 2.5, .max_gap = 0.2};
  const ResampleOptions back = parse_rule(rule_string(o));
  EXPECT_EQ(back.mapping, o.mapping);
  EXPECT_EQ(back.k, o.k);
  EXPECT_EQ(back.weights, o.weights);
  EXPECT_EQ(back.power, o.power);
  EXPECT_EQ(back.max_gap, o.max_gap);
  EXPECT_EQ(rule_string(parse_rule("weights=renka")), rule_string({.weights = Weights::renka}));  // defaults kept
  EXPECT_EQ(parse_rule("k=auto").k, 0u);
  EXPECT_THROW(check_options(parse_rule("k=auto")), UsageError);
  for (const char* bad : {"k=9x", "k=", "weights=gauss", "size=3", "k=3,k=4", "k", "power=abc"}) {
    try {
      parse_rule(bad);
      ADD_FAILURE() << bad;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("entry"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace specula::brdf
