#include "specula/acquire/bandwidth.h"

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "specula/acquire/store_samples.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {

namespace {

void check(const BandwidthOptions& b) {
  if (b.ladder.empty()) throw UsageError("choose_bandwidth: the ladder of k is empty");
  for (std::size_t l = 0; l < b.ladder.size(); ++l) {
    if (b.ladder[l] < 1 || b.ladder[l] > 100000) throw UsageError("choose_bandwidth: every k must be 1 to 100000");
    if (l > 0 && b.ladder[l] <= b.ladder[l - 1])
      throw UsageError("choose_bandwidth: the ladder of k must be strictly ascending");
  }
  if (b.held_out == 0) throw UsageError("choose_bandwidth: held_out must be at least 1");
  for (std::size_t e = 0; e < b.theta_h_edges.size(); ++e)
    if (!(b.theta_h_edges[e] > 0 && b.theta_h_edges[e] < 90) || (e > 0 && b.theta_h_edges[e] <= b.theta_h_edges[e - 1]))
      throw UsageError("choose_bandwidth: theta_h band edges must ascend within (0, 90) degrees");
}

// The rows of `rows_wanted` (ascending sample indices) read from src in its blocks, rows_wanted.size() x bands.
std::vector<float> read_rows(const brdf::SampleSource& src, std::span<const std::uint32_t> rows_wanted) {
  const std::size_t n = src.size(), bands = src.bands(), block_rows = std::max<std::size_t>(1, src.block_rows());
  std::vector<float> out(rows_wanted.size() * bands), block;
  std::size_t next = 0;
  for (std::size_t s0 = 0; s0 < n && next < rows_wanted.size(); s0 += block_rows) {
    check_interrupt();
    const std::size_t rows = std::min(block_rows, n - s0);
    if (rows_wanted[next] >= s0 + rows) continue;
    block.resize(rows * bands);
    src.read_values(s0, rows, block);
    for (; next < rows_wanted.size() && rows_wanted[next] < s0 + rows; ++next)
      std::copy_n(block.begin() + std::ptrdiff_t((rows_wanted[next] - s0) * bands), bands,
                  out.begin() + std::ptrdiff_t(next * bands));
  }
  return out;
}

// The angles of the held-out samples (ascending indices), read from src in its blocks: held.size() x 4.
std::vector<double> read_held_angles(const brdf::SampleSource& src, std::span<const std::size_t> held) {
  const std::size_t n = src.size(), block_rows = std::max<std::size_t>(1, src.block_rows());
  std::vector<double> out(4 * held.size()), block;
  std::size_t next = 0;
  for (std::size_t s0 = 0; s0 < n && next < held.size(); s0 += block_rows) {
    const std::size_t rows = std::min(block_rows, n - s0);
    if (held[next] >= s0 + rows) continue;
    block.resize(4 * rows);
    src.read_angles(s0, rows, block);
    for (; next < held.size() && held[next] < s0 + rows; ++next)
      std::copy_n(block.begin() + std::ptrdiff_t(4 * (held[next] - s0)), 4, out.begin() + std::ptrdiff_t(4 * next));
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// The criterion over the held-out samples j with use(j), sample j judged at ladder level level(j).
template <class Use, class Level>
double error_of(BandwidthCriterion c, const std::vector<double>& e2, const std::vector<double>& t2, std::size_t levels,
                Use use, Level level) {
  std::vector<double> rel;
  double se = 0, st = 0;
  for (std::size_t j = 0; j < t2.size(); ++j) {
    if (!use(j)) continue;
    const double e = e2[j * levels + level(j)];
    se += e;
    st += t2[j];
    if (t2[j] > 0) rel.push_back(std::sqrt(e / t2[j]));
  }
  if (c == BandwidthCriterion::median) return median(std::move(rel));
  return st > 0 ? std::sqrt(se / st) : 0.0;
}

// Sample j's nearest other samples, at most kmax + 1 (the reach of the largest k), itself left out.
void neighbours_without(const brdf::SampleTree& tree, const brdf::IsoAngles& at, std::size_t self, std::size_t kmax,
                        bool offsets, brdf::Neighbours& nb) {
  tree.nearest(at, kmax + 2, nb, offsets);
  auto it = std::find(nb.index.begin(), nb.index.end(), std::uint32_t(self));
  std::size_t drop = it == nb.index.end() ? nb.index.size() - 1 : std::size_t(it - nb.index.begin());
  nb.index.erase(nb.index.begin() + std::ptrdiff_t(drop));
  nb.dist2.erase(nb.dist2.begin() + std::ptrdiff_t(drop));
  if (offsets)
    nb.offset.erase(nb.offset.begin() + std::ptrdiff_t(3 * drop), nb.offset.begin() + std::ptrdiff_t(3 * drop + 3));
  const std::size_t keep = std::min(nb.index.size(), kmax + 1);
  nb.index.resize(keep);
  nb.dist2.resize(keep);
  if (offsets) nb.offset.resize(3 * keep);
}

// The held-out samples and their nearest other samples: kmax + 1 slots each (the reach of the largest k), `used`
// of them filled.
struct HeldOut {
  std::vector<std::size_t> held, band;
  std::size_t per = 0;
  std::vector<std::uint32_t> index, used;
  std::vector<float> dist2, offset;

  // Every sample a prediction uses, and the held-out ones, ascending.
  std::vector<std::uint32_t> wanted() const {
    std::vector<std::uint32_t> w;
    for (std::size_t j = 0; j < held.size(); ++j) {
      w.push_back(std::uint32_t(held[j]));
      w.insert(w.end(), index.begin() + std::ptrdiff_t(j * per), index.begin() + std::ptrdiff_t(j * per + used[j]));
    }
    std::sort(w.begin(), w.end());
    w.erase(std::unique(w.begin(), w.end()), w.end());
    return w;
  }
};

HeldOut find_held_out(const brdf::SampleTree& tree, const brdf::SampleSource& src, const brdf::ResampleOptions& o,
                      const BandwidthOptions& b, Progress& progress) {
  HeldOut ho;
  ho.held = select_indices(src.size(), std::min(b.held_out, src.size()), b.seed);
  const std::size_t h = ho.held.size(), kmax = b.ladder.back();
  const bool loess = o.weights == brdf::Weights::loess;
  ho.per = kmax + 1;
  ho.index.resize(h * ho.per);
  ho.used.resize(h);
  ho.dist2.resize(h * ho.per);
  ho.offset.resize(loess ? 3 * h * ho.per : 0);
  ho.band.resize(h);
  const std::vector<double> angles = read_held_angles(src, ho.held);
  parallel_for(
      h, [] { return brdf::Neighbours(); },
      [&](std::size_t j, brdf::Neighbours& nb) {
        const brdf::StdAngles a{angles[4 * j], angles[4 * j + 1], angles[4 * j + 2], angles[4 * j + 3]};
        neighbours_without(tree, brdf::iso_angles(a), ho.held[j], kmax, loess, nb);
        ho.used[j] = std::uint32_t(nb.index.size());
        std::copy(nb.index.begin(), nb.index.end(), ho.index.begin() + std::ptrdiff_t(j * ho.per));
        std::copy(nb.dist2.begin(), nb.dist2.end(), ho.dist2.begin() + std::ptrdiff_t(j * ho.per));
        if (loess) std::copy(nb.offset.begin(), nb.offset.end(), ho.offset.begin() + std::ptrdiff_t(3 * j * ho.per));
        const double th = brdf::half_diff(a).theta_h * 180 / std::numbers::pi;
        const auto& edges = b.theta_h_edges;
        ho.band[j] = std::size_t(std::upper_bound(edges.begin(), edges.end(), th) - edges.begin());
        progress.advance();
      },
      16);
  return ho;
}

// Squared error of every held-out sample at every ladder k (e2: h x levels) and its squared norm (t2), predicted
// with the weights a cell at its configuration would get from its neighbours.
void predict_held_out(const HeldOut& ho, const brdf::ResampleOptions& o, std::span<const std::size_t> ladder,
                      std::size_t bands, std::span<const std::uint32_t> wanted, std::span<const float> values,
                      std::vector<double>& e2, std::vector<double>& t2, Progress& progress) {
  const std::size_t h = ho.held.size(), levels = ladder.size(), per = ho.per;
  const bool loess = o.weights == brdf::Weights::loess, reach = brdf::weights_have_reach(o.weights);
  auto row_of = [&](std::uint32_t s) {
    return values.data() + std::size_t(std::lower_bound(wanted.begin(), wanted.end(), s) - wanted.begin()) * bands;
  };
  e2.assign(h * levels, 0);
  t2.assign(h, 0);
  using State = std::pair<std::vector<float>, std::vector<double>>;
  parallel_for(
      h, [&] { return State(std::vector<float>(per), std::vector<double>(bands)); },
      [&](std::size_t j, State& state) {
        auto& [w, acc] = state;
        const float* truth = row_of(std::uint32_t(ho.held[j]));
        for (std::size_t q = 0; q < bands; ++q) t2[j] += double(truth[q]) * truth[q];
        const float* d2 = ho.dist2.data() + j * per;
        for (std::size_t l = 0; l < levels; ++l) {
          const std::size_t k = std::min(ladder[l], std::size_t(ho.used[j]));
          const double reach2 = reach && ho.used[j] > k ? double(d2[k]) : std::numeric_limits<double>::infinity();
          const auto off =
              loess ? std::span<const float>(ho.offset.data() + 3 * j * per, 3 * k) : std::span<const float>();
          brdf::neighbour_weights(o.weights, o.power, {d2, k}, {w.data(), k}, reach2, off);
          std::fill(acc.begin(), acc.end(), 0.0);
          for (std::size_t i = 0; i < k; ++i) {
            const float* v = row_of(ho.index[j * per + i]);
            for (std::size_t q = 0; q < bands; ++q) acc[q] += double(w[i]) * v[q];
          }
          double se = 0;
          for (std::size_t q = 0; q < bands; ++q) {
            const double e = (loess ? std::max(0.0, acc[q]) : acc[q]) - truth[q];  // LOESS's cells are clamped at 0
            se += e * e;
          }
          e2[j * levels + l] = se;
        }
        progress.advance();
      },
      16);
}

// The mean of v over the bands that hold samples.
double band_mean(const std::vector<double>& v, const std::vector<std::size_t>& samples) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t g = 0; g < v.size(); ++g)
    if (samples[g] > 0) sum += v[g], ++n;
  return n ? sum / double(n) : 0.0;
}

// The rows, the global choice and the per-band choices from the squared errors.
BandwidthChoice summarise(const BandwidthOptions& b, const std::vector<double>& e2, const std::vector<double>& t2,
                          const std::vector<std::size_t>& band) {
  const std::size_t levels = b.ladder.size(), bands = b.theta_h_edges.size() + 1;
  const bool rms = b.criterion == BandwidthCriterion::rms;
  BandwidthChoice c;
  c.held_out = t2.size();
  c.band_samples.assign(bands, 0);
  for (const auto bj : band) ++c.band_samples[bj];
  auto all = [](std::size_t) { return true; };
  double best = std::numeric_limits<double>::infinity();
  std::vector<double> band_best(bands, std::numeric_limits<double>::infinity());
  c.band_k.assign(bands, b.ladder.front());
  std::vector<std::size_t> band_level(bands, 0);
  for (std::size_t l = 0; l < levels; ++l) {
    auto at = [l](std::size_t) { return l; };
    BandwidthRow r{.k = b.ladder[l],
                   .median_rel = error_of(BandwidthCriterion::median, e2, t2, levels, all, at),
                   .rel_rms = error_of(BandwidthCriterion::rms, e2, t2, levels, all, at)};
    for (std::size_t g = 0; g < bands; ++g) {
      auto in = [&](std::size_t j) { return band[j] == g; };
      r.band_median.push_back(error_of(BandwidthCriterion::median, e2, t2, levels, in, at));
      r.band_rms.push_back(error_of(BandwidthCriterion::rms, e2, t2, levels, in, at));
      const double e = rms ? r.band_rms[g] : r.band_median[g];
      if (c.band_samples[g] > 0 && e < band_best[g]) band_best[g] = e, c.band_k[g] = b.ladder[l], band_level[g] = l;
    }
    r.band_mean = band_mean(r.band_median, c.band_samples);
    const double e = rms ? r.rel_rms : b.criterion == BandwidthCriterion::median ? r.median_rel : r.band_mean;
    if (e < best) best = e, c.k = b.ladder[l];
    c.rows.push_back(std::move(r));
  }
  c.per_band_error =
      b.criterion == BandwidthCriterion::bands
          ? band_mean(band_best, c.band_samples)
          : error_of(b.criterion, e2, t2, levels, all, [&](std::size_t j) { return band_level[band[j]]; });
  return c;
}

}  // namespace

std::vector<std::size_t> select_indices(std::size_t n, std::size_t h, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::size_t> out;
  out.reserve(std::min(h, n));
  for (std::size_t i = 0; i < n && out.size() < h; ++i)
    if (rng() % (n - i) < h - out.size()) out.push_back(i);
  return out;
}

BandwidthCriterion parse_bandwidth_criterion(std::string_view name) {
  if (name == "bands") return BandwidthCriterion::bands;
  if (name == "median") return BandwidthCriterion::median;
  if (name == "rms") return BandwidthCriterion::rms;
  throw UsageError(fmt::format("unknown bandwidth criterion '{}': give bands, median or rms", name));
}

std::string_view bandwidth_criterion_name(BandwidthCriterion c) {
  return c == BandwidthCriterion::bands ? "bands" : c == BandwidthCriterion::median ? "median" : "rms";
}

BandwidthChoice choose_bandwidth(const brdf::SampleTree& tree, const brdf::SampleSource& src,
                                 const brdf::ResampleOptions& o, const BandwidthOptions& b) {
  check(b);
  check_options(o);
  if (tree.mapping() != o.mapping || tree.size() != src.size())
    throw UsageError("choose_bandwidth: the tree was built over other samples or with another mapping");
  if (src.size() < 2) throw InputError(fmt::format("choosing k needs at least 2 samples, got {}", src.size()));
  Progress progress("choosing k", 2 * std::min(b.held_out, src.size()));
  const HeldOut ho = find_held_out(tree, src, o, b, progress);
  const std::vector<std::uint32_t> wanted = ho.wanted();
  const std::vector<float> values = read_rows(src, wanted);
  std::vector<double> e2, t2;
  predict_held_out(ho, o, b.ladder, src.bands(), wanted, values, e2, t2, progress);
  return summarise(b, e2, t2, ho.band);
}

BandwidthChoice choose_bandwidth(const store::Store& store, const std::string& samples, const brdf::ResampleOptions& o,
                                 const BandwidthOptions& b) {
  const StoreSamples src(store, samples);
  const brdf::SampleTree tree(src, o.mapping);
  brdf::ResampleOptions at_most = o;
  at_most.k = b.ladder.empty() ? o.k : b.ladder.back();
  return choose_bandwidth(tree, src, at_most, b);
}

nlohmann::ordered_json bandwidth_choice_json(const BandwidthChoice& c, const BandwidthOptions& b) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const auto& r : c.rows)
    rows.push_back({{"k", r.k},
                    {"band_mean", r.band_mean},
                    {"median_rel", r.median_rel},
                    {"rel_rms", r.rel_rms},
                    {"band_median", r.band_median},
                    {"band_rms", r.band_rms}});
  return {{"k", c.k},
          {"criterion", bandwidth_criterion_name(b.criterion)},
          {"held_out", c.held_out},
          {"seed", b.seed},
          {"ladder", b.ladder},
          {"theta_h_edges_deg", b.theta_h_edges},
          {"band_samples", c.band_samples},
          {"band_k", c.band_k},
          {"per_band_error", c.per_band_error},
          {"rows", rows}};
}

std::string bandwidth_provenance(const BandwidthChoice& c, const BandwidthOptions& b) {
  return fmt::format("k={} k_auto=loo criterion={} held_out={} seed={}", c.k, bandwidth_criterion_name(b.criterion),
                     c.held_out, b.seed);
}

}  // namespace specula::acquire
