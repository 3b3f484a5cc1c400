// choose_bandwidth (acquire/bandwidth.h) against a leave-one-out selection written here by brute force (every
// sample's distance to every other, Wendland's kernel by hand, theta_h from the half vector), on noisy samples of a
// smooth function whose best bandwidth lies inside the ladder; and its independence of thread count and blocking.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>

#include "specula/acquire/bandwidth.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

struct Noisy {
  std::vector<double> angles;
  std::vector<float> values;  // 2 bands
  std::vector<Eigen::Vector3d> mapped;
  std::vector<double> theta_h_deg;
};

Eigen::Vector3d dir(double t, double p) { return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)}; }

// n samples at random configurations of f = 1 + 0.5 sin(3 theta_i) cos(2 theta_o) + 0.3 cos(2 phi_d) and 0.5 + 0.2 f,
// each band with 10 % Gaussian noise (relative to 1).
Noisy noisy_samples(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> t(0, pi / 2 - 0.01), p(-pi, pi);
  std::normal_distribution<double> noise(0, 0.1);
  Noisy s;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = t(rng), pi_ = p(rng), to = t(rng), po = p(rng);
    double pd = std::fmod(std::abs(po - pi_), 2 * pi);
    if (pd > pi) pd = 2 * pi - pd;
    const double f = 1 + 0.5 * std::sin(3 * ti) * std::cos(2 * to) + 0.3 * std::cos(2 * pd);
    s.angles.insert(s.angles.end(), {ti, pi_, to, po});
    s.values.push_back(float(f + noise(rng)));
    s.values.push_back(float(0.5 + 0.2 * f + noise(rng)));
    s.mapped.emplace_back(ti, to, pd);
    s.theta_h_deg.push_back(std::acos((dir(ti, pi_) + dir(to, po)).normalized().z()) * 180 / pi);
  }
  return s;
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Brute {
  std::vector<double> median, rms;
  std::vector<std::vector<double>> band_median;  // [level][band]
};

// Leave-one-out over every sample: Wendland's weighted mean of the k nearest others, R the (k+1)-th's distance.
Brute brute_force(const Noisy& s, const std::vector<std::size_t>& ladder, const std::vector<double>& edges) {
  const std::size_t n = s.mapped.size();
  Brute out;
  for (const std::size_t k : ladder) {
    std::vector<double> rel;
    std::vector<std::vector<double>> in_band(edges.size() + 1);
    double se = 0, st = 0;
    for (std::size_t j = 0; j < n; ++j) {
      std::vector<std::pair<double, std::size_t>> d;
      for (std::size_t i = 0; i < n; ++i)
        if (i != j) d.emplace_back((s.mapped[i] - s.mapped[j]).norm(), i);
      std::sort(d.begin(), d.end());
      const double reach = d[k].first;
      double pred[2] = {0, 0}, wsum = 0;
      for (std::size_t m = 0; m < k; ++m) {
        const double r = d[m].first / reach, w = std::pow(1 - r, 4) * (4 * r + 1);
        wsum += w;
        for (int q = 0; q < 2; ++q) pred[q] += w * s.values[2 * d[m].second + q];
      }
      double e2 = 0, t2 = 0;
      for (int q = 0; q < 2; ++q) {
        const double truth = s.values[2 * j + q];
        e2 += std::pow(pred[q] / wsum - truth, 2);
        t2 += truth * truth;
      }
      se += e2;
      st += t2;
      rel.push_back(std::sqrt(e2 / t2));
      const auto g = std::size_t(std::upper_bound(edges.begin(), edges.end(), s.theta_h_deg[j]) - edges.begin());
      in_band[g].push_back(rel.back());
    }
    out.median.push_back(median_of(rel));
    out.rms.push_back(std::sqrt(se / st));
    out.band_median.emplace_back();
    for (const auto& b : in_band) out.band_median.back().push_back(b.empty() ? 0.0 : median_of(b));
  }
  return out;
}

const std::vector<std::size_t> kLadder = {2, 4, 8, 16, 32, 64, 128};

TEST(Bandwidth, TheChosenKIsTheBruteForceLeaveOneOutMinimum) {
  const Noisy s = noisy_samples(700, 11);
  const brdf::MemorySamples src(s.angles, s.values, 2);
  const brdf::ResampleOptions o{.k = 128, .weights = brdf::Weights::wendland};
  const brdf::SampleTree tree(src, o.mapping);
  const BandwidthOptions b{.ladder = kLadder, .held_out = 5000, .criterion = BandwidthCriterion::median};
  const BandwidthChoice c = choose_bandwidth(tree, src, o, b);
  const Brute bf = brute_force(s, kLadder, b.theta_h_edges);
  const auto best = std::size_t(std::min_element(bf.median.begin(), bf.median.end()) - bf.median.begin());
  // The data are made so that neither end of the ladder is best: too few neighbours keep the noise, too many the bias.
  ASSERT_GT(best, 0u);
  ASSERT_LT(best, kLadder.size() - 1);
  EXPECT_EQ(c.k, kLadder[best]);
  EXPECT_EQ(c.held_out, 700u);
  ASSERT_EQ(c.rows.size(), kLadder.size());
  for (std::size_t l = 0; l < kLadder.size(); ++l) {
    EXPECT_NEAR(c.rows[l].median_rel, bf.median[l], 1e-5) << kLadder[l];
    EXPECT_NEAR(c.rows[l].rel_rms, bf.rms[l], 1e-5) << kLadder[l];
    for (std::size_t g = 0; g < bf.band_median[l].size(); ++g)
      EXPECT_NEAR(c.rows[l].band_median[g], bf.band_median[l][g], 1e-5) << kLadder[l] << " band " << g;
  }
  std::size_t total = 0;
  for (const auto m : c.band_samples) total += m;
  EXPECT_EQ(total, 700u);
  // The default criterion: each theta_h band's median counts alike (every band holds samples here).
  std::vector<double> band_mean;
  for (const auto& m : bf.band_median) band_mean.push_back(std::accumulate(m.begin(), m.end(), 0.0) / double(m.size()));
  const BandwidthChoice d = choose_bandwidth(tree, src, o, {.ladder = kLadder, .held_out = 5000});
  EXPECT_EQ(d.k, kLadder[std::size_t(std::min_element(band_mean.begin(), band_mean.end()) - band_mean.begin())]);
  for (std::size_t l = 0; l < kLadder.size(); ++l) EXPECT_NEAR(d.rows[l].band_mean, band_mean[l], 1e-5);
  // The rms criterion picks the brute force's rms minimum.
  const BandwidthChoice r =
      choose_bandwidth(tree, src, o, {.ladder = kLadder, .held_out = 5000, .criterion = BandwidthCriterion::rms});
  EXPECT_EQ(r.k, kLadder[std::size_t(std::min_element(bf.rms.begin(), bf.rms.end()) - bf.rms.begin())]);
}

// Values served a few rows at a time, as a store serves them in chunks.
class SmallBlocks final : public brdf::SampleSource {
 public:
  explicit SmallBlocks(const brdf::MemorySamples& m) : m_(m) {}
  std::size_t size() const override { return m_.size(); }
  std::size_t bands() const override { return m_.bands(); }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override {
    m_.read_angles(first, count, out);
  }
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override {
    m_.read_values(first, count, out);
  }
  std::size_t block_rows() const override { return 37; }

 private:
  const brdf::MemorySamples& m_;
};

void expect_same(const BandwidthChoice& a, const BandwidthChoice& b) {
  EXPECT_EQ(a.k, b.k);
  EXPECT_EQ(a.band_k, b.band_k);
  EXPECT_EQ(a.per_band_error, b.per_band_error);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (std::size_t l = 0; l < a.rows.size(); ++l) {
    EXPECT_EQ(a.rows[l].band_mean, b.rows[l].band_mean);
    EXPECT_EQ(a.rows[l].median_rel, b.rows[l].median_rel);
    EXPECT_EQ(a.rows[l].rel_rms, b.rows[l].rel_rms);
    EXPECT_EQ(a.rows[l].band_median, b.rows[l].band_median);
  }
}

TEST(Bandwidth, TheSameChoiceOnAnyThreadCountAndBlocking) {
  const Noisy s = noisy_samples(3000, 12);
  const brdf::MemorySamples src(s.angles, s.values, 2);
  const SmallBlocks blocks(src);
  for (const brdf::Weights w : {brdf::Weights::shepard, brdf::Weights::loess}) {
    const brdf::ResampleOptions o{.weights = w};
    const brdf::SampleTree tree(src, o.mapping);
    const BandwidthOptions b{.ladder = {4, 16, 64}, .held_out = 400, .seed = 3};
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const BandwidthChoice one = choose_bandwidth(tree, src, o, b);
    omp_set_num_threads(2);
    const BandwidthChoice two = choose_bandwidth(tree, blocks, o, b);
    omp_set_num_threads(saved);
    EXPECT_EQ(one.held_out, 400u);
    expect_same(one, two);
    // Another seed holds out other samples.
    const BandwidthChoice other = choose_bandwidth(tree, src, o, {.ladder = {4, 16, 64}, .held_out = 400, .seed = 4});
    EXPECT_NE(one.rows[0].median_rel, other.rows[0].median_rel);
  }
}

TEST(Bandwidth, RefusesBadOptions) {
  const Noisy s = noisy_samples(50, 13);
  const brdf::MemorySamples src(s.angles, s.values, 2);
  const brdf::ResampleOptions o{.weights = brdf::Weights::wendland};
  const brdf::SampleTree tree(src, o.mapping);
  EXPECT_THROW(choose_bandwidth(tree, src, o, {.ladder = {}}), UsageError);
  EXPECT_THROW(choose_bandwidth(tree, src, o, {.ladder = {8, 4}}), UsageError);
  EXPECT_THROW(choose_bandwidth(tree, src, o, {.ladder = {0, 4}}), UsageError);
  EXPECT_THROW(choose_bandwidth(tree, src, o, {.held_out = 0}), UsageError);
  EXPECT_THROW(choose_bandwidth(tree, src, o, {.theta_h_edges = {30, 10}}), UsageError);
  EXPECT_THROW(choose_bandwidth(tree, src, {.mapping = brdf::Mapping::halfdiff}, {}), UsageError);
  EXPECT_THROW(parse_bandwidth_criterion("mean"), UsageError);
  const brdf::MemorySamples one(std::span<const double>(s.angles).first(4), std::span<const float>(s.values).first(2),
                                2);
  const brdf::SampleTree tree1(one, o.mapping);
  EXPECT_THROW(choose_bandwidth(tree1, one, o, {}), InputError);
}

}  // namespace
}  // namespace specula::acquire
