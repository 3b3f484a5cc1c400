#pragma once
// The bandwidth of a resample chosen from the data (`resample -k auto`): every k of a fixed ladder judged by
// leave-one-out prediction of a fixed-seed subset of the samples from all the others, with exactly the neighbours
// and weights a grid cell at that sample's configuration would get, and the k with the lowest error kept. The
// error is also reported per theta_h band, to show whether one global k leaves accuracy behind.
#include <cstddef>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "specula/core/brdf_resample.h"

namespace specula::store {
class Store;
}  // namespace specula::store

namespace specula::acquire {

/// What the leave-one-out error of a k is judged by.
enum class BandwidthCriterion {
  /// The mean over theta_h bands (those with held-out samples) of each band's median relative error: every band
  /// counts alike, so the few samples near the specular peak are not outvoted by the many diffuse ones.
  bands,
  median,  ///< the median over held-out samples of |pred - true| / |true| (spectra as vectors)
  rms,     ///< sqrt(sum |pred - true|^2 / sum |true|^2) over held-out samples and bands
};

/// Parses "bands", "median" or "rms"; UsageError naming the choices otherwise.
BandwidthCriterion parse_bandwidth_criterion(std::string_view name);
/// "bands", "median" or "rms".
std::string_view bandwidth_criterion_name(BandwidthCriterion c);

struct BandwidthOptions {
  std::vector<std::size_t> ladder = {4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128};  ///< ascending, each >= 1
  std::size_t held_out = 2000;  ///< samples left out one at a time (all of them when there are fewer)
  std::uint64_t seed = 0;       ///< seed of the choice of held-out samples
  BandwidthCriterion criterion = BandwidthCriterion::bands;
  /// Upper edges (degrees) of the theta_h bands the error is also reported in; the last band ends at 90.
  std::vector<double> theta_h_edges = {10, 30, 60};
};

/// The leave-one-out errors of one k, over all held-out samples and per theta_h band.
struct BandwidthRow {
  std::size_t k = 0;
  double band_mean = 0, median_rel = 0, rel_rms = 0;  ///< bands, median and rms of BandwidthCriterion
  std::vector<double> band_median, band_rms;          ///< per theta_h band (0 for a band without held-out samples)
};

/// What the choice found.
struct BandwidthChoice {
  std::size_t k = 0;                      ///< the ladder's k of lowest error under the criterion (the smaller on a tie)
  std::size_t held_out = 0;               ///< samples predicted
  std::vector<std::size_t> band_samples;  ///< held-out samples per theta_h band
  std::vector<std::size_t> band_k;        ///< per theta_h band, the k of lowest error there
  /// The criterion over all held-out samples when each band uses its own band_k (what a per-band k would gain).
  double per_band_error = 0;
  std::vector<BandwidthRow> rows;  ///< one per ladder entry
};

/// min(h, n) of the indices [0, n), ascending, by Knuth's selection sampling (algorithm S) with a generator seeded by
/// seed: the same indices on every run.
std::vector<std::size_t> select_indices(std::size_t n, std::size_t h, std::uint64_t seed);

/// The leave-one-out choice of o.k for resampling src with o's mapping and weights: o.held_out samples picked by
/// selection sampling seeded by o.seed, each predicted from its nearest other samples (however far; no support
/// limit) for every ladder k, with the weights a cell there would get; the values streamed once in blocks, on all
/// threads with the same result for any thread count. UsageError for an empty or unsorted ladder, a k of 0 or
/// above 100000, held_out 0 or edges not ascending in (0, 90); InputError when src has fewer than 2 samples.
BandwidthChoice choose_bandwidth(const brdf::SampleTree& tree, const brdf::SampleSource& src,
                                 const brdf::ResampleOptions& o, const BandwidthOptions& b);
/// choose_bandwidth over the samples object `samples` of `store`, indexed by o's mapping.
BandwidthChoice choose_bandwidth(const store::Store& store, const std::string& samples, const brdf::ResampleOptions& o,
                                 const BandwidthOptions& b);
/// The choice and every ladder row's errors, as `resample --json` reports them under "k_auto".
nlohmann::ordered_json bandwidth_choice_json(const BandwidthChoice& c, const BandwidthOptions& b);
/// "k=K k_auto=loo criterion=C held_out=N seed=S": how the grid's provenance names a chosen k.
std::string bandwidth_provenance(const BandwidthChoice& c, const BandwidthOptions& b);

}  // namespace specula::acquire
