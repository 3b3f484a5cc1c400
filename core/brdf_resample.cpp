#include "specula/core/brdf_resample.h"

#include <fmt/format.h>

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>

#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/merl_cells.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::brdf {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// How many neighbours a query needs: Renka's and the smoothing weights also need the (k+1)-th nearest sample's
// distance, the reach.
std::size_t wanted(const ResampleOptions& o) { return weights_have_reach(o.weights) ? o.k + 1 : o.k; }

// The weights of a query's neighbours, reordered by sample index so that every band is accumulated in the same
// order wherever the values come from (memory or blocks of a file).
struct WeightedNeighbours {
  std::vector<float> w;
  std::vector<std::pair<std::uint32_t, float>> by_sample;

  // nb: the query's wanted(o) nearest, in any order; left in ascending sample index. False when the query has no
  // support. With a reach, the farthest neighbour (by distance, then sample index: the (k+1)-th nearest) gives it
  // and is dropped.
  bool weigh(Neighbours& nb, const ResampleOptions& o) {
    if (nb.index.empty() || !(nb.gap <= o.max_gap)) return false;
    order_by_sample(nb);
    double reach2 = std::numeric_limits<double>::infinity();
    if (weights_have_reach(o.weights) && nb.index.size() > o.k) {
      std::size_t far = 0;
      for (std::size_t j = 1; j < nb.index.size(); ++j)
        if (nb.dist2[j] >= nb.dist2[far]) far = j;
      reach2 = nb.dist2[far];
      nb.index.erase(nb.index.begin() + std::ptrdiff_t(far));
      nb.dist2.erase(nb.dist2.begin() + std::ptrdiff_t(far));
      if (!nb.offset.empty())
        nb.offset.erase(nb.offset.begin() + std::ptrdiff_t(3 * far), nb.offset.begin() + std::ptrdiff_t(3 * far + 3));
    }
    w.resize(nb.index.size());
    neighbour_weights(o.weights, o.power, nb.dist2, w, reach2, nb.offset);
    by_sample.resize(nb.index.size());
    for (std::size_t j = 0; j < nb.index.size(); ++j) by_sample[j] = {nb.index[j], w[j]};
    return true;
  }

 private:
  std::vector<std::size_t> order;
  Neighbours sorted;

  void order_by_sample(Neighbours& nb) {
    if (std::is_sorted(nb.index.begin(), nb.index.end())) return;
    order.resize(nb.index.size());
    std::iota(order.begin(), order.end(), std::size_t(0));
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return nb.index[a] < nb.index[b]; });
    sorted.index.resize(order.size());
    sorted.dist2.resize(order.size());
    sorted.offset.resize(nb.offset.size());
    for (std::size_t j = 0; j < order.size(); ++j) {
      sorted.index[j] = nb.index[order[j]];
      sorted.dist2[j] = nb.dist2[order[j]];
      if (!nb.offset.empty())
        std::copy_n(nb.offset.begin() + std::ptrdiff_t(3 * order[j]), 3, sorted.offset.begin() + std::ptrdiff_t(3 * j));
    }
    std::swap(nb.index, sorted.index);
    std::swap(nb.dist2, sorted.dist2);
    std::swap(nb.offset, sorted.offset);
  }
};

// A row of grid cells (neighbours along phi_d) with their queries and neighbours, per thread.
struct CellRow {
  std::vector<IsoAngles> at;
  std::vector<Neighbours> nb;
  WeightedNeighbours wn;
};

// Cells per row searched together (SampleTree::nearest_each): consecutive cells of one (theta_h, theta_d).
constexpr std::size_t kRowCells = 16;

// Starts of the rows of cells[first, first + m), then m.
std::vector<std::size_t> cell_rows(std::span<const std::uint32_t> cells, std::size_t first, std::size_t m) {
  std::vector<std::size_t> starts;
  for (std::size_t c = 0; c < m; ++c)
    if (starts.empty() || c - starts.back() == kRowCells || cells[first + c] / 180 != cells[first + c - 1] / 180)
      starts.push_back(c);
  starts.push_back(m);
  return starts;
}

// A cell's value from its accumulated sum: LOESS's weights may be negative, and a BRDF is not.
float estimate(Weights w, double sum) { return float(w == Weights::loess ? std::max(0.0, sum) : sum); }

using ValueReader = std::function<void(std::size_t first, std::size_t count, std::span<float> out)>;

// Where a fill writes: band-major (bands x cells, -1 where a cell has no data) or cell-major (cells x bands and a
// flag per cell, both untouched where a cell has no data); gaps when asked for.
struct GridOut {
  std::span<float> grid;
  bool cell_major = false;
  std::span<std::uint8_t> valid = {};
  std::span<float> gaps = {};
};

// What filling a grid reads and writes.
struct GridFill {
  const SampleTree& tree;
  const ResampleOptions& o;
  std::size_t n, bands;
  GridOut out;
  std::span<const std::uint32_t> cells;  // the valid cells filled, ascending

  // Finds and weighs the neighbours of cells[first, first + m), row by row on all threads, and calls
  // visit(c, by_sample) for each cell c (from first) with support; the gaps are written when asked for.
  template <class Visit>
  void weigh_cells(std::size_t first, std::size_t m, const Visit& visit) const {
    Progress progress("finding neighbours", m);
    const std::vector<std::size_t> rows = cell_rows(cells, first, m);
    const std::size_t batch = 1 << 11;
    for (std::size_t r0 = 0; r0 + 1 < rows.size(); r0 += batch) {
      check_interrupt();
      const std::size_t r1 = std::min(rows.size() - 1, r0 + batch);
      parallel_for(
          r1 - r0, [] { return CellRow(); },
          [&](std::size_t r, CellRow& row) {
            const std::size_t c0 = rows[r0 + r], c1 = rows[r0 + r + 1];
            row.at.resize(c1 - c0);
            row.nb.resize(c1 - c0);
            const MerlCell head = merl_cell(cells[first + c0]);
            const MerlCentres centres(head.theta_h, head.theta_d);
            for (std::size_t c = c0; c < c1; ++c)
              row.at[c - c0] = iso_angles(centres.std_angles(merl_cell(cells[first + c]).phi_d));
            // Only whether a gap exceeds max_gap matters, unless the gaps are written.
            tree.nearest_each(row.at, wanted(o), row.nb, o.weights == Weights::loess, out.gaps.empty() ? o.max_gap : 0);
            for (std::size_t c = c0; c < c1; ++c) {
              Neighbours& nb = row.nb[c - c0];
              if (!out.gaps.empty()) out.gaps[cells[first + c]] = float(nb.gap);
              if (row.wn.weigh(nb, o)) visit(c, std::span<const std::pair<std::uint32_t, float>>(row.wn.by_sample));
            }
          },
          8);
      progress.advance(rows[r1] - rows[r0]);
    }
  }

  void store(std::size_t cell, const double* acc) const {
    if (!out.cell_major) {
      for (std::size_t q = 0; q < bands; ++q) out.grid[q * kMerlCells + cell] = estimate(o.weights, acc[q]);
      return;
    }
    for (std::size_t q = 0; q < bands; ++q) out.grid[cell * bands + q] = estimate(o.weights, acc[q]);
    out.valid[cell] = 1;
  }
};

void add_weighted(double* acc, const float* v, double w, std::size_t bands) {
  for (std::size_t q = 0; q < bands; ++q) acc[q] += w * double(v[q]);
}

// Values read whole are held with each sample's bands padded with zeros to a whole number of lanes of four doubles.
std::size_t padded_bands(std::size_t bands) { return (bands + 3) / 4 * 4; }

// acc[0, P) = the sum of w v over the neighbours in order (values: P floats a sample), in registers: a sum through
// memory waits on its own store at every neighbour. Each band's sum is add_weighted's.
template <std::size_t P>
void weighted_sum(std::span<const std::pair<std::uint32_t, float>> by_sample, const float* values, double* acc) {
  using Lanes = Eigen::Array<double, Eigen::Index(P), 1>;
  Lanes a = Lanes::Zero();
  for (const auto& [s, w] : by_sample)
    a += double(w) *
         Eigen::Map<const Eigen::Array<float, Eigen::Index(P), 1>>(values + std::size_t(s) * P).template cast<double>();
  Eigen::Map<Lanes> out(acc);
  out = a;
}

template <std::size_t... P>
void weighted_sum(std::span<const std::pair<std::uint32_t, float>> by_sample, const float* values, std::size_t stride,
                  double* acc, std::index_sequence<P...>) {
  if (((stride == 4 * (P + 1) ? (weighted_sum<4 * (P + 1)>(by_sample, values, acc), true) : false) || ...)) return;
  std::fill_n(acc, stride, 0.0);
  for (const auto& [s, w] : by_sample) add_weighted(acc, values + std::size_t(s) * stride, w, stride);
}

// Every cell summed as soon as its weights are known, from values read whole (padded_bands(f.bands) a sample).
GridStats fill_from_memory(const GridFill& f, std::span<const float> values) {
  GridStats stats;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::uint8_t> valid(f.cells.size(), 0);
  const std::size_t stride = padded_bands(f.bands);
  thread_local std::vector<double> acc;
  f.weigh_cells(0, f.cells.size(), [&](std::size_t c, std::span<const std::pair<std::uint32_t, float>> by_sample) {
    acc.resize(stride);
    weighted_sum(by_sample, values.data(), stride, acc.data(), std::make_index_sequence<16>());
    f.store(f.cells[c], acc.data());
    valid[c] = 1;
  });
  stats.passes = 1;
  stats.valid_cells = std::size_t(std::count(valid.begin(), valid.end(), 1));
  stats.query_seconds = seconds_since(t0);
  return stats;
}

// Neighbour lists of at most max_entries entries at a time, the values streamed past them once per pass.
GridStats fill_streaming(const GridFill& f, const ValueReader& read, std::size_t block_rows) {
  GridStats stats;
  const std::size_t k = std::min(f.o.k, f.n), bands = f.bands;
  const std::size_t per_pass = std::max<std::size_t>(1, f.o.max_entries / k);
  std::vector<std::uint32_t> count, cursor, sample;
  std::vector<float> weight, block;
  std::vector<double> acc;
  for (std::size_t first = 0; first < f.cells.size(); first += per_pass) {
    const std::size_t m = std::min(per_pass, f.cells.size() - first);
    ++stats.passes;
    count.assign(m, 0);
    sample.resize(m * k);
    weight.resize(m * k);
    auto t0 = std::chrono::steady_clock::now();
    f.weigh_cells(first, m, [&](std::size_t c, std::span<const std::pair<std::uint32_t, float>> by_sample) {
      count[c] = std::uint32_t(by_sample.size());
      for (std::size_t j = 0; j < by_sample.size(); ++j) {
        sample[c * k + j] = by_sample[j].first;
        weight[c * k + j] = by_sample[j].second;
      }
    });
    stats.query_seconds += seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    acc.assign(m * bands, 0.0);
    cursor.assign(m, 0);
    Progress progress("averaging", f.n);
    for (std::size_t s0 = 0; s0 < f.n; s0 += block_rows) {
      check_interrupt();
      const std::size_t rows = std::min(block_rows, f.n - s0);
      block.resize(rows * bands);
      read(s0, rows, block);
      const auto s1 = std::uint32_t(s0 + rows);
      parallel_for(
          m,
          [&](std::size_t c) {
            std::uint32_t j = cursor[c];
            for (; j < count[c] && sample[c * k + j] < s1; ++j)
              add_weighted(acc.data() + c * bands, block.data() + (sample[c * k + j] - s0) * bands, weight[c * k + j],
                           bands);
            cursor[c] = j;
          },
          4096);
      progress.advance(rows);
    }
    for (std::size_t c = 0; c < m; ++c) {
      if (count[c] == 0) continue;
      ++stats.valid_cells;
      f.store(f.cells[first + c], acc.data() + c * bands);
    }
    stats.average_seconds += seconds_since(t0);
  }
  return stats;
}

// The second half of resample_grid. Each cell's value is the weighted sum of its neighbours', band by band in
// ascending sample index, whichever way the values arrive: read whole when they take no more memory than a pass's
// neighbour lists would (max_entries entries of 8 bytes), else streamed past the lists.
GridStats fill(const SampleTree& tree, std::size_t n, std::size_t bands, const ValueReader& read,
               std::size_t block_rows, const ResampleOptions& o, const GridOut& out,
               std::span<const std::uint32_t> cells) {
  check_options(o);
  if (!out.gaps.empty() && out.gaps.size() != kMerlCells)
    throw UsageError("resample: gaps must hold one value per cell");
  if (o.mapping != tree.mapping()) throw UsageError("resample: the options' mapping differs from the tree's");
  if (bands == 0 || out.grid.size() != bands * kMerlCells)
    throw UsageError("resample: the grid must hold bands x 90 x 90 x 180 values");
  if (out.cell_major && out.valid.size() != kMerlCells) throw UsageError("resample: valid must hold one flag per cell");
  if (!out.cell_major) std::fill(out.grid.begin(), out.grid.end(), -1.0f);
  const GridFill f{.tree = tree, .o = o, .n = n, .bands = bands, .out = out, .cells = cells};
  block_rows = std::max<std::size_t>(1, block_rows);
  GridStats stats;
  const std::size_t stride = padded_bands(bands);
  if (n * stride * sizeof(float) <= o.max_entries * 8) {
    Buffer<float> values;  // every entry written below: the bands, then the padding's zeros
    values.resize(n * stride);
    std::vector<float> block;
    for (std::size_t s0 = 0; s0 < n; s0 += block_rows) {
      const std::size_t rows = std::min(block_rows, n - s0);
      block.resize(rows * bands);
      read(s0, rows, block);
      for (std::size_t i = 0; i < rows; ++i) {
        float* to = values.data() + (s0 + i) * stride;
        std::copy_n(block.begin() + std::ptrdiff_t(i * bands), bands, to);
        std::fill(to + bands, to + stride, 0.0f);
      }
    }
    stats = fill_from_memory(f, values);
  } else {
    stats = fill_streaming(f, read, block_rows);
  }
  stats.samples = n;
  return stats;
}

// fill over the values of src.
GridStats fill_source(const SampleTree& tree, const SampleSource& src, const ResampleOptions& o, const GridOut& out,
                      std::span<const std::uint32_t> cells) {
  if (tree.size() != src.size()) throw UsageError("resample: the tree was built over other samples");
  return fill(
      tree, src.size(), src.bands(),
      [&src](std::size_t first, std::size_t count, std::span<float> out) { src.read_values(first, count, out); },
      src.block_rows(), o, out, cells);
}

}  // namespace

std::string rule_string(const ResampleOptions& o) {
  std::ostringstream out;
  out.precision(17);
  out << "mapping=" << mapping_name(o.mapping) << ",weights=" << weights_name(o.weights) << ",k=" << o.k
      << ",power=" << o.power << ",max_gap=" << o.max_gap;
  return out.str();
}

ResampleOptions parse_rule(std::string_view text) {
  ResampleOptions o;
  std::vector<std::string_view> seen;
  for (std::size_t at = 0; at <= text.size();) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    const std::string_view entry = text.substr(at, end - at);
    at = end + 1;
    const std::size_t eq = entry.find('=');
    const std::string_view key = entry.substr(0, eq), value = eq == entry.npos ? "" : entry.substr(eq + 1);
    const auto bad = [&](const char* why) {
      return UsageError("resampling rule '" + std::string(text) + "': entry '" + std::string(entry) + "' " + why +
                        " (give mapping=, weights=, k= (a count or auto), power=, max_gap=, comma-separated)");
    };
    if (eq == entry.npos || value.empty()) throw bad("is not key=value");
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) throw bad("repeats its key");
    seen.push_back(key);
    const std::string v(value);
    std::size_t used = 0;
    try {
      if (key == "mapping") {
        o.mapping = parse_mapping(v), used = v.size();
      } else if (key == "weights") {
        o.weights = parse_weights(v), used = v.size();
      } else if (key == "k") {
        o.k = v == "auto" ? 0 : std::stoul(v, &used);
        if (v == "auto")
          used = v.size();
        else if (o.k == 0)
          throw bad("asks for no neighbours (give 1 or more, or auto)");
      } else if (key == "power") {
        o.power = std::stod(v, &used);
      } else if (key == "max_gap") {
        o.max_gap = std::stod(v, &used);
      } else {
        throw bad("has an unknown key");
      }
    } catch (const UsageError& e) {
      throw bad(e.what());
    } catch (const std::logic_error&) {
      throw bad("has a value that is not a number");
    }
    if (used != v.size()) throw bad("has a value that is not a number");
  }
  return o;
}

void check_options(const ResampleOptions& o) {
  if (o.k < 1 || o.k > 100000) throw UsageError("k = " + std::to_string(o.k) + ": give 1 to 100000 neighbours");
  if (!(o.power >= 0) || !std::isfinite(o.power))
    throw UsageError(fmt::format("power = {:g}: Shepard's power must be a finite number >= 0", o.power));
  if (o.power != 1 && o.weights != Weights::shepard)
    throw UsageError(fmt::format("power = {:g}: only Shepard's weights have a power", o.power));
  if (!(o.max_gap > 0)) throw UsageError(fmt::format("max_gap = {:g}: the largest gap must be positive", o.max_gap));
  if (o.max_entries == 0) throw UsageError("resample: max_entries must be positive");
}

// ------------------------------------------------------------------ sources

void SampleSource::read_variance(std::size_t, std::size_t, std::span<float>) const {
  throw UsageError("these samples carry no variance");
}

MemorySamples::MemorySamples(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                             std::span<const float> variance)
    : angles_(angles), values_(values), variance_(variance), bands_(bands) {
  if (bands == 0 || angles.size() % 4 != 0 || values.size() != angles.size() / 4 * bands ||
      !(variance.empty() || variance.size() == values.size()))
    throw UsageError("resample: angles must be n x 4, values n x bands and variance empty or n x bands");
}

void MemorySamples::read_angles(std::size_t first, std::size_t count, std::span<double> out) const {
  if (first + count > size() || out.size() != 4 * count) throw UsageError("MemorySamples::read_angles: bad range");
  std::copy_n(angles_.begin() + std::ptrdiff_t(4 * first), 4 * count, out.begin());
}

void MemorySamples::read_values(std::size_t first, std::size_t count, std::span<float> out) const {
  if (first + count > size() || out.size() != bands_ * count) throw UsageError("MemorySamples::read_values: bad range");
  std::copy_n(values_.begin() + std::ptrdiff_t(bands_ * first), bands_ * count, out.begin());
}

void MemorySamples::read_variance(std::size_t first, std::size_t count, std::span<float> out) const {
  if (variance_.empty()) SampleSource::read_variance(first, count, out);
  if (first + count > size() || out.size() != bands_ * count)
    throw UsageError("MemorySamples::read_variance: bad range");
  std::copy_n(variance_.begin() + std::ptrdiff_t(bands_ * first), bands_ * count, out.begin());
}

// ------------------------------------------------------------------ reconstruction

GridStats resample_grid(const SampleTree& tree, const SampleSource& src, const ResampleOptions& o,
                        std::span<float> grid, std::span<float> gaps) {
  return fill_source(tree, src, o, {.grid = grid, .gaps = gaps}, merl_valid_cells());
}

GridStats resample_cells(const SampleTree& tree, const SampleSource& src, const ResampleOptions& o,
                         std::span<const std::uint32_t> cells, std::span<float> grid, std::span<float> gaps) {
  const auto& valid = merl_valid_cells();
  for (std::size_t c = 0; c < cells.size(); ++c)
    if ((c > 0 && cells[c] <= cells[c - 1]) || !std::binary_search(valid.begin(), valid.end(), cells[c]))
      throw UsageError(
          fmt::format("resample: cell {} (at {}) is not a valid MERL cell above the one before it; "
                      "give valid cells in ascending order",
                      cells[c], c));
  return fill_source(tree, src, o, {.grid = grid, .gaps = gaps}, cells);
}

GridStats resample_grid(const SampleSource& src, const ResampleOptions& o, std::span<float> grid) {
  check_options(o);
  if (grid.size() != src.bands() * kMerlCells)
    throw UsageError("resample: the grid must hold bands x 90 x 90 x 180 values");
  const auto t0 = std::chrono::steady_clock::now();
  const SampleTree tree(src, o.mapping);
  const double tree_seconds = seconds_since(t0);
  GridStats stats = resample_grid(tree, src, o, grid);
  stats.tree_seconds = tree_seconds;
  return stats;
}

Resampler::Resampler(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                     const ResampleOptions& o)
    : values_(values), bands_(bands), o_(o) {
  check_options(o);
  const MemorySamples src(angles, values, bands);
  tree_ = std::make_shared<const SampleTree>(src, o.mapping);
}

Resampler::Resampler(std::shared_ptr<const SampleTree> tree, std::span<const float> values, std::size_t bands,
                     const ResampleOptions& o)
    : tree_(std::move(tree)), values_(values), bands_(bands), o_(o) {
  check_options(o);
  if (!tree_ || o.mapping != tree_->mapping())
    throw UsageError("resample: the options' mapping differs from the tree's");
  if (bands == 0 || values.size() != tree_->size() * bands) throw UsageError("resample: values must be n x bands");
}

bool Resampler::predict(const IsoAngles& at, std::span<float> out) const {
  if (out.size() != bands_) throw UsageError("Resampler::predict: out must hold one value per band");
  thread_local Neighbours nb;
  thread_local WeightedNeighbours wn;
  thread_local std::vector<double> acc;
  tree_->nearest(at, wanted(o_), nb, o_.weights == Weights::loess);
  if (!wn.weigh(nb, o_)) return false;
  acc.assign(bands_, 0.0);
  for (const auto& [s, w] : wn.by_sample) {
    const float* v = values_.data() + std::size_t(s) * bands_;
    for (std::size_t q = 0; q < bands_; ++q) acc[q] += double(w) * double(v[q]);
  }
  for (std::size_t q = 0; q < bands_; ++q) out[q] = estimate(o_.weights, acc[q]);
  return true;
}

bool Resampler::predict(const StdAngles& at, std::span<float> out) const { return predict(iso_angles(at), out); }

void Resampler::neighbours(const StdAngles& at, Neighbours& out) const { tree_->nearest(iso_angles(at), o_.k, out); }

std::size_t Resampler::fill(std::span<float> grid, bool cell_major, std::span<std::uint8_t> valid) const {
  const std::size_t b = bands_;
  const auto values = values_;
  return brdf::fill(
             *tree_, tree_->size(), b,
             [values, b](std::size_t first, std::size_t count, std::span<float> out) {
               std::copy_n(values.begin() + std::ptrdiff_t(first * b), count * b, out.begin());
             },
             std::size_t(1) << 16, o_, {.grid = grid, .cell_major = cell_major, .valid = valid}, merl_valid_cells())
      .valid_cells;
}

std::size_t Resampler::fill_grid(std::span<float> grid) const { return fill(grid, false, {}); }

std::size_t Resampler::fill_cells(std::span<float> values, std::span<std::uint8_t> valid) const {
  return fill(values, true, valid);
}

}  // namespace specula::brdf
