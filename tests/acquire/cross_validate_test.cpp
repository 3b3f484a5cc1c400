#include "specula/acquire/cross_validate.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "specula/acquire/synth_samples.h"
#include "specula/core/brdf_mapping.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

struct Samples {
  std::vector<double> angles;
  std::vector<float> values;
  std::size_t bands = 0;
};

Samples ward_samples(std::size_t n) {
  const WavelengthGrid g = WavelengthGrid::parse("500:600:50");
  const auto model = brdf::make_material("study-ward", g);
  Samples s;
  s.bands = g.size();
  random_configurations(n, 11, 0, s.angles);
  s.values.resize(n * s.bands);
  brdf::evaluate_at(*model, s.angles, s.values);
  return s;
}

// The row of `mapping`, k and weights, or fails.
const CrossValidationRow& row(const CrossValidation& cv, brdf::Mapping m, std::size_t k, brdf::Weights w) {
  for (const auto& r : cv.rows)
    if (r.mapping == m && r.k == k && r.weights == w) return r;
  ADD_FAILURE() << "no row for k " << k;
  return cv.rows.front();
}

TEST(CrossValidate, OneRowPerMappingKAndWeightingInOrder) {
  const Samples s = ward_samples(400);
  const CrossValidation cv = cross_validate(s.angles, s.values, s.bands, {.holdout = 0.1, .seed = 3, .ks = {1, 8}});
  EXPECT_EQ(cv.samples, 400u);
  EXPECT_EQ(cv.held_out, 40u);
  ASSERT_EQ(cv.rows.size(), 3u * 6u);  // per mapping: k = 1 once, k = 8 mean, Shepard, Renka, Wendland, LOESS
  std::size_t i = 0;
  for (const brdf::Mapping m : {brdf::Mapping::standard, brdf::Mapping::marschner, brdf::Mapping::halfdiff}) {
    EXPECT_EQ(cv.rows[i].mapping, m);
    EXPECT_EQ(cv.rows[i].k, 1u);
    EXPECT_EQ(cv.rows[i].weights, brdf::Weights::mean);
    EXPECT_EQ(cv.rows[i + 1].weights, brdf::Weights::mean);
    EXPECT_EQ(cv.rows[i + 2].weights, brdf::Weights::shepard);
    EXPECT_EQ(cv.rows[i + 3].weights, brdf::Weights::renka);
    EXPECT_EQ(cv.rows[i + 4].weights, brdf::Weights::wendland);
    EXPECT_EQ(cv.rows[i + 5].weights, brdf::Weights::loess);
    for (std::size_t j = i; j < i + 6; ++j) EXPECT_EQ(cv.rows[j].predicted, 40u);  // no support limit
    i += 6;
  }
}

// A BRDF that is the same everywhere is predicted exactly by any neighbours and weights.
TEST(CrossValidate, AConstantBrdfIsPredictedWithoutError) {
  Samples s = ward_samples(300);
  for (std::size_t i = 0; i < s.values.size(); ++i) s.values[i] = 0.25f + 0.125f * float(i % s.bands);
  const CrossValidation cv = cross_validate(s.angles, s.values, s.bands, {.holdout = 0.2, .seed = 1, .ks = {1, 4}});
  for (const auto& r : cv.rows) {
    EXPECT_EQ(r.predicted, 60u);
    EXPECT_NEAR(r.rel_rms, 0, 1e-6);
    EXPECT_NEAR(r.median_rel, 0, 1e-6);
  }
}

// Brute force: the same split (the documented shuffle), each held-out sample predicted by the mean of its k nearest
// training samples in the mapped space, searched exhaustively.
TEST(CrossValidate, MeanPredictionsMatchABruteForceNearestNeighbourSearch) {
  const Samples s = ward_samples(500);
  const std::size_t n = 500, b = s.bands;
  const CrossValidationOptions o{.holdout = 0.15, .seed = 9, .ks = {1, 5}};
  const CrossValidation cv = cross_validate(s.angles, s.values, b, o);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(o.seed);
  std::shuffle(order.begin(), order.end(), rng);
  const std::size_t held = std::size_t(std::llround(o.holdout * double(n)));
  auto at = [&](std::size_t i) {
    return brdf::StdAngles{s.angles[4 * i], s.angles[4 * i + 1], s.angles[4 * i + 2], s.angles[4 * i + 3]};
  };
  for (const brdf::Mapping m : {brdf::Mapping::standard, brdf::Mapping::marschner, brdf::Mapping::halfdiff})
    for (const std::size_t k : o.ks) {
      double err = 0, ref = 0;
      std::vector<double> rel;
      for (std::size_t j = 0; j < held; ++j) {
        const Eigen::Vector3f q = brdf::map_angles(m, at(order[j])).cast<float>();
        std::vector<std::pair<float, std::size_t>> d;
        for (std::size_t t = held; t < n; ++t)
          d.push_back({(brdf::map_angles(m, at(order[t])).cast<float>() - q).squaredNorm(), order[t]});
        std::partial_sort(d.begin(), d.begin() + std::ptrdiff_t(k), d.end());
        double se = 0, st = 0;
        for (std::size_t c = 0; c < b; ++c) {
          double mean = 0;
          for (std::size_t i = 0; i < k; ++i) mean += s.values[d[i].second * b + c];
          mean /= double(k);
          const double truth = s.values[order[j] * b + c];
          se += (mean - truth) * (mean - truth);
          st += truth * truth;
        }
        err += se;
        ref += st;
        if (st > 0) rel.push_back(std::sqrt(se / st));
      }
      std::nth_element(rel.begin(), rel.begin() + std::ptrdiff_t(rel.size() / 2), rel.end());
      const CrossValidationRow& r = row(cv, m, k, brdf::Weights::mean);
      EXPECT_EQ(r.predicted, held);
      EXPECT_NEAR(r.rel_rms, std::sqrt(err / ref), 1e-5 * std::sqrt(err / ref)) << brdf::mapping_name(m) << " k " << k;
      EXPECT_NEAR(r.median_rel, rel[rel.size() / 2], 1e-5 * rel[rel.size() / 2]) << brdf::mapping_name(m) << " k " << k;
    }
}

TEST(CrossValidate, RowsDoNotDependOnTheThreadCount) {
  const int saved = omp_get_max_threads();
  const Samples s = ward_samples(3000);
  const CrossValidationOptions o{.holdout = 0.3, .seed = 2, .ks = {1, 16}};
  omp_set_num_threads(1);
  const CrossValidation one = cross_validate(s.angles, s.values, s.bands, o);
  omp_set_num_threads(2);
  const CrossValidation two = cross_validate(s.angles, s.values, s.bands, o);
  omp_set_num_threads(saved);
  ASSERT_EQ(one.rows.size(), two.rows.size());
  for (std::size_t i = 0; i < one.rows.size(); ++i) {
    EXPECT_EQ(one.rows[i].rel_rms, two.rows[i].rel_rms);
    EXPECT_EQ(one.rows[i].median_rel, two.rows[i].median_rel);
    EXPECT_EQ(one.rows[i].predicted, two.rows[i].predicted);
  }
}

TEST(CrossValidate, RejectsBadOptionsNamingTheParameter) {
  const Samples s = ward_samples(50);
  for (const double h : {0.0, 1.0, 1.5, -0.2}) {
    try {
      cross_validate(s.angles, s.values, s.bands, {.holdout = h});
      ADD_FAILURE() << h;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("holdout"), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find("--"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(cross_validate(s.angles, s.values, s.bands, {.ks = {4, 0}}), UsageError);
  EXPECT_THROW(cross_validate(s.angles, std::span<const float>(s.values).first(10), s.bands, {}), UsageError);
  // 50 samples at 0.001 hold out round(0.05) = 0.
  EXPECT_THROW(cross_validate(s.angles, s.values, s.bands, {.holdout = 0.001}), InputError);
}

}  // namespace
}  // namespace specula::acquire
