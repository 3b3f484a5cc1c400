#pragma once
// Scattered BRDF samples onto the MERL grid (reference §5.3, algorithm 3D_BRDF_Resample): the samples'
// configurations mapped into 3D (core/brdf_mapping.h), a kd-tree over them (nanoflann), and at every query (a
// grid cell's centre, or any configuration) the k nearest samples combined with one set of weights for every
// band: their mean, Shepard's inverse distances to the power p (eqs 5.9-5.10), Franke-Little's (Renka's
// modified Shepard) weights, which fall to 0 at the (k+1)-th nearest sample so that the estimate is continuous
// where the neighbour set changes, or two approximating (smoothing) estimates with the same continuous reach:
// Wendland's C2 kernel, and a local linear (LOESS) fit weighted by it, whose equivalent weights reproduce any
// linear function of the mapped coordinates exactly.
//
// A grid's cells are searched a row at a time (consecutive phi_d of one theta_h, theta_d): the row shares one
// search of the tree for candidates, among which each cell picks its own k nearest, exactly those a search for the
// cell alone finds (ties go to the lower sample index everywhere).
//
// Out of core: a grid is filled in two streams over the samples. The angles are read in blocks and mapped
// into the tree (16 bytes per sample); the neighbours and weights of the cells are found; then the values are
// read in blocks and each cell accumulates its neighbours' values as their block passes. Only the mapped
// points, the neighbour lists and the grid are held. When the values take no more memory than those lists would
// (o.max_entries x 8 bytes), they are read whole instead and each cell is summed as soon as it is weighed, with
// the same sums in the same order.
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_mapping.h"

namespace specula::brdf {

enum class Weights { mean, shepard, renka, wendland, loess };

/// Parses "mean", "shepard", "renka", "wendland" or "loess"; UsageError naming the choices otherwise.
Weights parse_weights(std::string_view name);
/// "mean", "shepard", "renka", "wendland" or "loess".
std::string_view weights_name(Weights w);

/// True for the weightings whose weights fall to 0 at the (k+1)-th nearest sample, the reach (renka, wendland, loess).
bool weights_have_reach(Weights w);

/// The default largest gap, in degrees: what `specula resample --max-gap` offers, and ResampleOptions' default.
inline constexpr double kDefaultMaxGapDegrees = 8.6;

struct ResampleOptions {
  Mapping mapping = Mapping::standard;
  std::size_t k = 32;
  Weights weights = Weights::shepard;
  double power = 1;  ///< Shepard's p; the other weightings have none
  /// A query has no support (a cell is left without data) when its nearest sample is farther than this in
  /// config_distance (about radians; reciprocal as the mapping).
  double max_gap = kDefaultMaxGapDegrees * std::numbers::pi / 180;
  /// Neighbour entries (cells x k, 8 bytes each) held at once while filling a grid; more cells take further
  /// passes over the sample values.
  std::size_t max_entries = std::size_t(64) << 20;
};

/// The rule of o, every field, as parse_rule reads it: "mapping=M,weights=W,k=K,power=P,max_gap=G".
std::string rule_string(const ResampleOptions& o);
/// Options from comma-separated key=value entries (mapping, weights, k, power, max_gap; each at most once) over
/// the defaults; "k=auto" leaves k = 0 for the caller to choose (check_options refuses it). UsageError naming the
/// entry otherwise.
ResampleOptions parse_rule(std::string_view text);

/// UsageError stating the rule when k is not 1 to 100000, power not finite and >= 0 (or not 1 without Shepard's
/// weights), max_gap not positive or max_entries 0.
void check_options(const ResampleOptions& o);

/// Scattered samples that can be read in blocks: size() samples of bands() values each.
class SampleSource {
 public:
  virtual ~SampleSource() = default;
  virtual std::size_t size() const = 0;
  virtual std::size_t bands() const = 0;
  /// Angles of samples [first, first + count) into out (count x 4: theta_i, phi_i, theta_o, phi_o, radians).
  virtual void read_angles(std::size_t first, std::size_t count, std::span<double> out) const = 0;
  /// Values of samples [first, first + count) into out (count x bands()).
  virtual void read_values(std::size_t first, std::size_t count, std::span<float> out) const = 0;
  /// Samples per read that suit the source.
  virtual std::size_t block_rows() const { return std::size_t(1) << 16; }
  /// Whether each value carries its noise variance (read_variance).
  virtual bool has_variance() const { return false; }
  /// Variances of samples [first, first + count) into out (count x bands(), units^2); UsageError without them.
  virtual void read_variance(std::size_t first, std::size_t count, std::span<float> out) const;
};

/// Samples held by the caller (who keeps them alive): angles n x 4, values n x bands.
class MemorySamples final : public SampleSource {
 public:
  /// UsageError when the sizes disagree or bands is 0; variance empty (none) or one per value.
  MemorySamples(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                std::span<const float> variance = {});
  std::size_t size() const override { return angles_.size() / 4; }
  std::size_t bands() const override { return bands_; }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override;
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override;
  bool has_variance() const override { return !variance_.empty(); }
  void read_variance(std::size_t first, std::size_t count, std::span<float> out) const override;

 private:
  std::span<const double> angles_;
  std::span<const float> values_, variance_;
  std::size_t bands_;
};

/// The k nearest samples of a query and how far the nearest one is.
struct Neighbours {
  std::vector<std::uint32_t> index;  ///< sample indices, nearest first
  std::vector<float> dist2;          ///< squared distances in the mapped space
  std::vector<float> offset;         ///< 3 per neighbour: its mapped point minus the query's (when asked for)
  /// config_distance from the query to the nearest sample (reciprocal as the mapping); a search given a gap_cap may
  /// hold instead an upper bound of it no larger than gap_cap (so gap <= gap_cap exactly when the distance is).
  double gap = 0;
};

/// A kd-tree (nanoflann) over the mapped configurations of a source's samples: 16 bytes per sample.
class SampleTree {
 public:
  /// Reads the angles of src in blocks and builds the tree; InputError for no samples or 2^32 or more.
  SampleTree(const SampleSource& src, Mapping m);
  ~SampleTree();
  SampleTree(const SampleTree&) = delete;
  SampleTree& operator=(const SampleTree&) = delete;

  Mapping mapping() const { return mapping_; }
  std::size_t size() const { return n_; }
  /// The min(k, size()) nearest samples of `at` into out, nearest first (ties: lower sample index first); their offsets
  /// only when `offsets` (else out.offset is emptied).
  void nearest(const IsoAngles& at, std::size_t k, Neighbours& out, bool offsets = false) const;
  /// For each query the neighbours nearest(at[i], k, out[i], offsets) finds, though not always nearest first, found
  /// together: queries that lie close (a row of grid cells) share one search of the tree; gaps within gap_cap may
  /// be bounds (Neighbours::gap). UsageError when out and at differ in size.
  void nearest_each(std::span<const IsoAngles> at, std::size_t k, std::span<Neighbours> out, bool offsets = false,
                    double gap_cap = 0) const;

 private:
  template <class Set>
  void search(const float* q, Set& result) const;
  void finish(const IsoAngles& at, const float* q, std::uint32_t nearest, Neighbours& out, bool offsets,
              double gap_cap) const;
  void nearest_row(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k, std::span<Neighbours> out,
                   bool offsets, double gap_cap) const;
  void split_row(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k, std::span<Neighbours> out,
                 bool offsets, double gap_cap, std::size_t len) const;
  void pick_nearest(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k,
                    std::span<const std::uint32_t> candidates, std::span<Neighbours> out, bool offsets,
                    double gap_cap) const;

  struct Index;
  Mapping mapping_;
  std::size_t n_ = 0;
  std::unique_ptr<Index> index_;
};

/// Normalised weights (summing to 1) of neighbours at squared mapped distances dist2 (any order) into out:
/// equal for mean; for Shepard d^-p (eq 5.10); for renka ((R - d)+ / (R d))^2 with R^2 = reach2 (the (k+1)-th
/// nearest sample's; infinite when there is none: 1/d^2); for wendland (1 - d/R)^4 (4 d/R + 1) and for loess the
/// local linear fit's equivalent weights with that kernel (offsets: 3 per neighbour, mapped; they may be
/// negative), both with R as for renka (infinite: the farthest neighbour's distance x 1.5); equal among the nearest
/// when all fall at R; for shepard and renka, samples at distance 0, if any, share all the weight. UsageError for
/// loess without offsets.
void neighbour_weights(Weights w, double power, std::span<const float> dist2, std::span<float> out,
                       double reach2 = std::numeric_limits<double>::infinity(), std::span<const float> offsets = {});

/// Timing and counts of one grid reconstruction.
struct GridStats {
  std::size_t samples = 0, valid_cells = 0, passes = 0;
  double tree_seconds = 0, query_seconds = 0, average_seconds = 0;
};

/// Every physically valid MERL cell's centre reconstructed from src into grid (bands x 90 x 90 x 180, band
/// slowest); cells below the horizon or without support get -1. Streams src twice (angles, then values whole or
/// once per pass of at most o.max_entries neighbour entries); OpenMP over cells, the same grid for any thread count;
/// progress shown, Interrupted between blocks. UsageError for a grid of the wrong size or bad options.
GridStats resample_grid(const SampleSource& src, const ResampleOptions& o, std::span<float> grid);
/// resample_grid with a tree already built over src (o.mapping must be the tree's); when gaps is given
/// (kMerlCells values), each valid cell's config_distance to its nearest sample goes there (others untouched).
GridStats resample_grid(const SampleTree& tree, const SampleSource& src, const ResampleOptions& o,
                        std::span<float> grid, std::span<float> gaps = {});
/// resample_grid at `cells` alone (valid MERL cell indices, ascending), each exactly as resample_grid computes it;
/// the grid's other cells get -1 and the other gaps are left untouched. UsageError for a cell not valid or out of
/// order.
GridStats resample_cells(const SampleTree& tree, const SampleSource& src, const ResampleOptions& o,
                         std::span<const std::uint32_t> cells, std::span<float> grid, std::span<float> gaps = {});

/// Reconstruction at any configuration from samples in memory (the caller keeps the values alive).
class Resampler {
 public:
  /// Builds a tree over angles (n x 4, radians); values n x bands. UsageError for bad options or sizes,
  /// InputError for no samples.
  Resampler(std::span<const double> angles, std::span<const float> values, std::size_t bands, const ResampleOptions& o);
  /// Shares a tree built over the same samples (o.mapping must be the tree's), so that k and weights can vary cheaply.
  Resampler(std::shared_ptr<const SampleTree> tree, std::span<const float> values, std::size_t bands,
            const ResampleOptions& o);

  std::size_t size() const { return tree_->size(); }
  std::size_t bands() const { return bands_; }
  const ResampleOptions& options() const { return o_; }
  /// The reconstruction at `at` into out (bands values), exactly as resample_grid computes a cell; false (out
  /// untouched) without support.
  bool predict(const StdAngles& at, std::span<float> out) const;
  /// predict at an isotropic configuration.
  bool predict(const IsoAngles& at, std::span<float> out) const;
  /// The k nearest samples of `at`.
  void neighbours(const StdAngles& at, Neighbours& out) const;
  /// resample_grid over these samples; returns the number of cells with data.
  std::size_t fill_grid(std::span<float> grid) const;
  /// fill_grid cell by cell: a cell's bands together in values (90 x 90 x 180 x bands) and valid[cell] = 1, both
  /// left untouched where a cell has no data; returns the number of cells with data. UsageError for wrong sizes.
  std::size_t fill_cells(std::span<float> values, std::span<std::uint8_t> valid) const;

 private:
  std::size_t fill(std::span<float> grid, bool cell_major, std::span<std::uint8_t> valid) const;

  std::shared_ptr<const SampleTree> tree_;
  std::span<const float> values_;
  std::size_t bands_;
  ResampleOptions o_;
};

}  // namespace specula::brdf
