#include "specula/core/brdf_resample.h"

#include <nanoflann.hpp>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

// SampleTree: the kd-trees (nanoflann) over the samples' mapped configurations, and the searches in them.
namespace specula::brdf {
namespace {

// Mapped points, three floats each, for nanoflann: while a slab's tree is built it sees only that slab;
// afterwards every tree reads the whole array by position.
struct Cloud {
  const float* xyz = nullptr;
  std::size_t count = 0;
  std::size_t kdtree_get_point_count() const { return count; }
  float kdtree_get_pt(std::uint32_t i, std::size_t d) const { return xyz[3 * std::size_t(i) + d]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud, float, std::uint32_t>,
                                                   Cloud, 3, std::uint32_t>;

// The k nearest points by (squared distance, sample index), nearest first. Ties at the k-th distance go to the
// lower sample index, not to whichever point the tree visits first, so that every search of the same samples
// (one query at a time or a row of them) finds the same neighbours.
class NearestSet {
 public:
  NearestSet(std::size_t k, const std::uint32_t* sample, std::uint32_t* pos, float* d2)
      : k_(k), sample_(sample), pos_(pos), d2_(d2) {}
  std::size_t size() const { return count_; }
  bool full() const { return count_ == k_; }
  // Just above the k-th distance, so that a tie with it is still offered to addPoint.
  float worstDist() const {
    return full() ? std::nextafter(d2_[k_ - 1], std::numeric_limits<float>::infinity())
                  : std::numeric_limits<float>::max();
  }
  bool addPoint(float d, std::uint32_t p) {
    // Sample indices are looked up only for ties: they lie far apart in memory.
    const auto ahead = [&](std::size_t j) { return d2_[j] < d || (d2_[j] == d && sample_[pos_[j]] < sample_[p]); };
    if (full() && ahead(k_ - 1)) return true;
    std::size_t i = full() ? k_ - 1 : count_++;
    for (; i > 0 && !ahead(i - 1); --i) {
      d2_[i] = d2_[i - 1];
      pos_[i] = pos_[i - 1];
    }
    d2_[i] = d;
    pos_[i] = p;
    return true;
  }

 private:
  std::size_t k_, count_ = 0;
  const std::uint32_t* sample_;
  std::uint32_t* pos_;
  float* d2_;
};

// Every point nearer than sqrt(radius2), in no order; the search stops once more than `limit` are found.
class WithinSet {
 public:
  WithinSet(float radius2, std::size_t limit, std::vector<std::uint32_t>& pos)
      : radius2_(radius2), limit_(limit), pos_(pos) {}
  std::size_t size() const { return pos_.size(); }
  bool full() const { return true; }
  float worstDist() const { return radius2_; }
  bool addPoint(float d, std::uint32_t p) {
    if (d < radius2_) pos_.push_back(p);
    return pos_.size() <= limit_;
  }

 private:
  float radius2_;
  std::size_t limit_;
  std::vector<std::uint32_t>& pos_;
};

// Squared distance as the trees measure it (nanoflann's L2_Simple_Adaptor, in float, axis by axis).
float distance2(const float* q, const float* p) {
  float s = 0;
  for (std::size_t d = 0; d < 3; ++d) {
    const float t = q[d] - p[d];
    s += t * t;
  }
  return s;
}

// The k-th smallest squared distance from c to the points at positions pos of xyz (three floats a point; scratch: d2).
float kth_distance2(const float* c, std::span<const std::uint32_t> pos, std::size_t k, std::span<const float> xyz,
                    std::vector<float>& d2) {
  d2.resize(pos.size());
  for (std::size_t j = 0; j < pos.size(); ++j) {
    if (3 * std::size_t(pos[j]) >= xyz.size())
      throw std::logic_error("SampleTree: a row bounded by another tree's candidates");
    d2[j] = distance2(c, xyz.data() + 3 * std::size_t(pos[j]));
  }
  std::nth_element(d2.begin(), d2.begin() + std::ptrdiff_t(k - 1), d2.end());
  return d2[k - 1];
}

std::uint64_t next_serial() {
  static std::atomic<std::uint64_t> count{0};
  return ++count;
}

// The points are cut into slabs along one axis and every slab gets its own tree, so that the trees are built on
// all threads. The number of slabs depends on the number of points only: the same trees, neighbours and ties
// for any thread count.
std::size_t slab_count(std::size_t n) { return std::clamp<std::size_t>(n >> 20, 1, 8); }

// A row of queries is searched as one while its spread is at most this fraction of the k-th neighbour's distance
// from its centre: the candidates then fill a ball at most (1 + kRowSpread)^3 = 3.4 times the neighbours' volume.
constexpr float kRowSpread = 0.5f;
// Where density changes fast (an empty region beside a dense one) the ball may hold far more; a row is cut in
// halves when it holds over this many candidates per neighbour.
constexpr std::size_t kRowCandidates = 6;

Eigen::Vector3f mapped(Mapping m, const IsoAngles& a) { return map_angles(m, a).cast<float>(); }

// The k-th smallest of distinct keys, the k smallest left in keys[0, k): a few largest dropped one by one when only
// a few exceed k (branch-free passes), else nth_element.
std::uint64_t select_kth(std::span<std::uint64_t> keys, std::size_t k) {
  std::size_t n = keys.size();
  if (n - k > 8) {
    std::nth_element(keys.begin(), keys.begin() + std::ptrdiff_t(k - 1), keys.end());
    return keys[k - 1];
  }
  const auto largest = [&](std::size_t m) {
    std::uint64_t v = 0;
    for (std::size_t j = 0; j < m; ++j) v = std::max(v, keys[j]);
    return v;
  };
  for (; n > k; --n) {
    const std::uint64_t v = largest(n);
    *std::find(keys.begin(), keys.begin() + std::ptrdiff_t(n), v) = keys[n - 1];
  }
  return largest(k);
}

// The keys (bits of dist[j] << 32 | j) of the j < count with dist[j] <= limit, in ascending j, into keys (which
// has room for count + kKeepSlack); returns how many. Branch-free: each key is written, and passed only when kept.
constexpr std::size_t kKeepSlack = 16;
std::size_t keep_within(const float* dist, std::size_t count, float limit, std::uint64_t* keys) {
  std::size_t kept = 0, j = 0;
#if defined(__AVX512F__)
  const __m512 bound = _mm512_set1_ps(limit);
  const __m512i lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  for (; j + 16 <= count; j += 16) {
    const __m512 d = _mm512_loadu_ps(dist + j);
    const __mmask16 in = _mm512_cmp_ps_mask(d, bound, _CMP_LE_OQ);
    const __m512i bits = _mm512_castps_si512(d), at = _mm512_add_epi32(lanes, _mm512_set1_epi32(int(j)));
    for (int half = 0; half < 2; ++half) {
      const __m256i b = half ? _mm512_extracti64x4_epi64(bits, 1) : _mm512_castsi512_si256(bits);
      const __m256i a = half ? _mm512_extracti64x4_epi64(at, 1) : _mm512_castsi512_si256(at);
      const __m512i key = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(b), 32), _mm512_cvtepu32_epi64(a));
      const auto m = __mmask8(half ? in >> 8 : in);
      _mm512_storeu_si512(keys + kept, _mm512_maskz_compress_epi64(m, key));
      kept += std::size_t(std::popcount(unsigned(m)));
    }
  }
#endif
  for (; j < count; ++j) {
    keys[kept] = std::uint64_t(std::bit_cast<std::uint32_t>(dist[j])) << 32 | j;
    kept += dist[j] <= limit;
  }
  return kept;
}

// The candidates of the row a thread searched last, as positions in the tree numbered `tree`: any k of them bound
// the k-th neighbour's distance of the next row's centre from above, which spares that row its own k-nearest search.
// Only the speed depends on it; the neighbours found do not.
struct LastRow {
  std::uint64_t tree = 0;
  std::vector<std::uint32_t> pos;
  std::vector<float> d2;
};
thread_local LastRow last_row;

}  // namespace

struct SampleTree::Index {
  struct Slab {
    Cloud cloud;
    std::unique_ptr<KdTree> tree;
    float low = 0, high = 0;  // the slab's extent along the cut axis
  };
  std::vector<float> xyz;             // slab by slab, each in its tree's leaf order
  std::vector<std::uint32_t> sample;  // position -> sample index
  int axis = 0;
  std::vector<float> cuts;  // slab s holds cuts[s - 1] <= x[axis] < cuts[s]
  std::vector<std::unique_ptr<Slab>> slabs;
  std::uint64_t serial = next_serial();  // tells this tree's positions from another's in a thread's LastRow
};

SampleTree::SampleTree(const SampleSource& src, Mapping m)
    : mapping_(m), n_(src.size()), index_(std::make_unique<Index>()) {
  if (n_ == 0) throw InputError("no samples to resample");
  if (n_ >= std::numeric_limits<std::uint32_t>::max())
    throw InputError(std::to_string(n_) + " samples: at most 2^32 - 2 can be resampled at once; split them");
  std::vector<float> xyz(3 * n_);
  {
    Progress progress("mapping samples", n_);
    std::vector<double> angles;
    const std::size_t rows = src.block_rows();
    for (std::size_t s0 = 0; s0 < n_; s0 += rows) {
      check_interrupt();
      const std::size_t r = std::min(rows, n_ - s0);
      angles.resize(4 * r);
      src.read_angles(s0, r, angles);
      parallel_for(
          r,
          [&](std::size_t i) {
            const double* a = angles.data() + 4 * i;
            const Eigen::Vector3f p = mapped(m, iso_angles({a[0], a[1], a[2], a[3]}));
            for (std::size_t d = 0; d < 3; ++d) xyz[3 * (s0 + i) + d] = p[Eigen::Index(d)];
          },
          4096);
      progress.advance(r);
    }
  }
  Index& ix = *index_;
  const std::size_t slabs = slab_count(n_);
  ix.sample.resize(n_);
  std::vector<std::size_t> offset(slabs + 1, 0);
  if (slabs == 1) {
    ix.xyz = std::move(xyz);
    std::iota(ix.sample.begin(), ix.sample.end(), std::uint32_t(0));
    offset[1] = n_;
  } else {
    // Cut along the widest axis at quantiles of a regular subsample; a stable scatter keeps input order in a slab.
    Eigen::Array3f lo = Eigen::Array3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
    for (std::size_t i = 0; i < n_; ++i)
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], xyz[3 * i + std::size_t(d)]);
        hi[d] = std::max(hi[d], xyz[3 * i + std::size_t(d)]);
      }
    (hi - lo).maxCoeff(&ix.axis);
    const std::size_t axis = std::size_t(ix.axis), stride = std::max<std::size_t>(1, n_ / 65536);
    std::vector<float> pick;
    for (std::size_t i = 0; i < n_; i += stride) pick.push_back(xyz[3 * i + axis]);
    std::sort(pick.begin(), pick.end());
    for (std::size_t s = 1; s < slabs; ++s) ix.cuts.push_back(pick[s * pick.size() / slabs]);
    std::vector<std::uint8_t> slab_of(n_);
    for (std::size_t i = 0; i < n_; ++i) {
      slab_of[i] = std::uint8_t(std::upper_bound(ix.cuts.begin(), ix.cuts.end(), xyz[3 * i + axis]) - ix.cuts.begin());
      ++offset[slab_of[i] + 1];
    }
    for (std::size_t s = 0; s < slabs; ++s) offset[s + 1] += offset[s];
    ix.xyz.resize(3 * n_);
    std::vector<std::size_t> next(offset.begin(), offset.end() - 1);
    for (std::size_t i = 0; i < n_; ++i) {
      const std::size_t to = next[slab_of[i]]++;
      std::copy_n(xyz.begin() + std::ptrdiff_t(3 * i), 3, ix.xyz.begin() + std::ptrdiff_t(3 * to));
      ix.sample[to] = std::uint32_t(i);
    }
  }
  xyz = {};
  for (std::size_t s = 0; s < slabs; ++s) {
    auto slab = std::make_unique<Index::Slab>();
    slab->low = s == 0 ? -std::numeric_limits<float>::infinity() : ix.cuts[s - 1];
    slab->high = s + 1 == slabs ? std::numeric_limits<float>::infinity() : ix.cuts[s];
    ix.slabs.push_back(std::move(slab));
  }
  // Each slab's tree, built on its own thread; then its points stored in leaf order (a leaf's points contiguous
  // in memory) and the tree's permutation made the positions themselves.
  parallel_for(slabs, [&](std::size_t s) {
    const std::size_t first = offset[s], count = offset[s + 1] - offset[s];
    Index::Slab& slab = *ix.slabs[s];
    slab.cloud = {ix.xyz.data() + 3 * first, count};
    if (count == 0) return;
    slab.tree = std::make_unique<KdTree>(3, slab.cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    auto& order = slab.tree->vAcc;
    std::vector<float> points(ix.xyz.begin() + std::ptrdiff_t(3 * first),
                              ix.xyz.begin() + std::ptrdiff_t(3 * (first + count)));
    std::vector<std::uint32_t> ids(ix.sample.begin() + std::ptrdiff_t(first),
                                   ix.sample.begin() + std::ptrdiff_t(first + count));
    for (std::size_t j = 0; j < count; ++j) {
      std::copy_n(points.begin() + std::ptrdiff_t(3 * std::size_t(order[j])), 3,
                  ix.xyz.begin() + std::ptrdiff_t(3 * (first + j)));
      ix.sample[first + j] = ids[order[j]];
      order[j] = std::uint32_t(first + j);
    }
  });
  for (auto& slab : ix.slabs) slab->cloud = {ix.xyz.data(), n_};
}

SampleTree::~SampleTree() = default;

template <class Set>
void SampleTree::search(const float* q, Set& result) const {
  const Index& ix = *index_;
  // The query's own slab first, then the others outwards while they can still hold a nearer point.
  const auto slabs = static_cast<std::ptrdiff_t>(ix.slabs.size());
  const float x = q[ix.axis];
  const std::ptrdiff_t own = std::upper_bound(ix.cuts.begin(), ix.cuts.end(), x) - ix.cuts.begin();
  auto search = [&](std::ptrdiff_t s) {
    const auto& slab = *ix.slabs[std::size_t(s)];
    if (slab.tree) slab.tree->findNeighbors(result, q, nanoflann::SearchParams());
  };
  search(own);
  for (std::ptrdiff_t left = own - 1, right = own + 1; left >= 0 || right < slabs;) {
    const float gl = left >= 0 ? x - ix.slabs[std::size_t(left)]->high : std::numeric_limits<float>::infinity();
    const float gr = right < slabs ? ix.slabs[std::size_t(right)]->low - x : std::numeric_limits<float>::infinity();
    const bool go_left = gl <= gr;
    const float gap = go_left ? gl : gr;
    if (gap * gap > result.worstDist()) break;
    search(go_left ? left-- : right++);
  }
}

void SampleTree::finish(const IsoAngles& at, const float* q, std::uint32_t nearest, Neighbours& out, bool offsets,
                        double gap_cap) const {
  const Index& ix = *index_;
  const std::size_t found = out.index.size();
  out.offset.resize(offsets ? 3 * found : 0);
  out.gap = std::numeric_limits<double>::infinity();
  if (found == 0) return;
  if (offsets)
    for (std::size_t j = 0; j < found; ++j)
      for (std::size_t d = 0; d < 3; ++d) out.offset[3 * j + d] = ix.xyz[3 * std::size_t(out.index[j]) + d] - q[d];
  for (auto& i : out.index) i = ix.sample[i];
  const float* p = ix.xyz.data() + 3 * std::size_t(nearest);
  // The mapping's bound on the mapped distance, widened for q and p in float (at most 4.2e-7 from the exact points,
  // distances a few float roundings off), spares the trigonometry wherever it already settles gap <= gap_cap.
  const double bound = config_distance_bound(mapping_) * (std::sqrt(double(distance2(q, p))) * (1 + 1e-5) + 1e-5);
  out.gap = bound <= gap_cap ? bound
                             : config_distance(at, unmap(mapping_, Eigen::Vector3d(p[0], p[1], p[2])),
                                               mapping_is_reciprocal(mapping_));
}

void SampleTree::nearest(const IsoAngles& at, std::size_t k, Neighbours& out, bool offsets) const {
  const Eigen::Vector3f q = mapped(mapping_, at);
  nearest_row({&at, 1}, {q.data(), 3}, std::min(k, n_), {&out, 1}, offsets, 0);
}

void SampleTree::nearest_each(std::span<const IsoAngles> at, std::size_t k, std::span<Neighbours> out, bool offsets,
                              double gap_cap) const {
  if (out.size() != at.size()) throw UsageError("SampleTree::nearest_each: out must hold one entry per query");
  k = std::min(k, n_);
  thread_local std::vector<float> q;
  q.resize(3 * at.size());
  for (std::size_t i = 0; i < at.size(); ++i) {
    const Eigen::Vector3f p = mapped(mapping_, at[i]);
    std::copy_n(p.data(), 3, q.data() + 3 * i);
  }
  nearest_row(at, q, k, out, offsets, gap_cap);
}

// The row in pieces of `len` queries searched as rows, or one query at a time when len < 2.
void SampleTree::split_row(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k,
                           std::span<Neighbours> out, bool offsets, double gap_cap, std::size_t len) const {
  for (std::size_t i = 0; i < at.size(); i += std::max<std::size_t>(len, 1)) {
    if (len < 2) {
      nearest_row(at.subspan(i, 1), q.subspan(3 * i, 3), k, out.subspan(i, 1), offsets, gap_cap);
      continue;
    }
    const std::size_t l = std::min(len, at.size() - i);
    nearest_row(at.subspan(i, l), q.subspan(3 * i, 3 * l), k, out.subspan(i, l), offsets, gap_cap);
  }
}

// Queries [0, at.size()) as one search when they lie close together, else in shorter rows: any bound B >= d_k(c) of
// the row's centre c gives R = B + 2 r (r: the largest distance of a query from c), and every query's k nearest lie
// within R of c, since d_k(q) <= d_k(c) + r. B is the k-th distance from c to the previous row's candidates (any k
// points bound d_k(c)), or d_k(c) itself, searched for, when there are none or they hold too many within R. Among the
// points within R each query's nearest are found by distance and sample index, as NearestSet orders them.
void SampleTree::nearest_row(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k,
                             std::span<Neighbours> out, bool offsets, double gap_cap) const {
  const std::size_t m = at.size();
  if (m == 0 || k == 0) {
    for (std::size_t i = 0; i < m; ++i) {
      out[i].index.clear();
      out[i].dist2.clear();
      finish(at[i], q.data() + 3 * i, 0, out[i], offsets, gap_cap);
    }
    return;
  }
  if (m == 1) {  // one query: its own search, nearest first
    Neighbours& o = out[0];
    o.index.resize(k);
    o.dist2.resize(k);
    NearestSet result(k, index_->sample.data(), o.index.data(), o.dist2.data());
    search(q.data(), result);
    o.index.resize(result.size());
    o.dist2.resize(result.size());
    finish(at[0], q.data(), o.index[0], o, offsets, gap_cap);
    return;
  }
  float c[3] = {0, 0, 0};
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t d = 0; d < 3; ++d) c[d] += q[3 * i + d] / float(m);
  float r2 = 0;
  for (std::size_t i = 0; i < m; ++i) r2 = std::max(r2, distance2(c, q.data() + 3 * i));
  const float r = std::sqrt(r2);
  thread_local std::vector<std::uint32_t> pos;
  for (const bool bounded : {true, false}) {
    float dk = 0;
    if (bounded) {
      if (last_row.tree != index_->serial || last_row.pos.size() < k) continue;
      dk = std::sqrt(kth_distance2(c, last_row.pos, k, index_->xyz, last_row.d2));
    } else {
      pos.resize(k);
      last_row.d2.resize(k);
      NearestSet centre(k, index_->sample.data(), pos.data(), last_row.d2.data());
      search(c, centre);
      dk = std::sqrt(last_row.d2[centre.size() - 1]);
    }
    if (2 * r > kRowSpread * dk)  // shorter rows, as long as the spread allows
      return split_row(at, q, k, out, offsets, gap_cap, std::size_t(float(m) * kRowSpread * dk / (2 * r)));
    const float reach = (dk + 2 * r) * (1 + 1e-5f);
    pos.clear();
    // > 0 when the row sits on a sample
    WithinSet within(reach * reach + std::numeric_limits<float>::min(), kRowCandidates * k, pos);
    search(c, within);
    if (pos.size() > kRowCandidates * k) {
      if (bounded) continue;                                           // the bound was loose: the exact d_k(c)
      return split_row(at, q, k, out, offsets, gap_cap, (m + 1) / 2);  // an empty region beside a dense one: halves
    }
    if (pos.size() < k) throw std::logic_error("SampleTree::nearest_each: fewer candidates than neighbours");
    last_row.tree = index_->serial;
    last_row.pos.assign(pos.begin(), pos.end());
    pick_nearest(at, q, k, pos, out, offsets, gap_cap);
    return;
  }
}

// Each query's k nearest among the candidate positions (which hold them all), in ascending sample index; keys of
// squared distance and rank by sample index, so that ties fall as NearestSet lets them.
void SampleTree::pick_nearest(std::span<const IsoAngles> at, std::span<const float> q, std::size_t k,
                              std::span<const std::uint32_t> candidates, std::span<Neighbours> out, bool offsets,
                              double gap_cap) const {
  const Index& ix = *index_;
  // (sample index << 32 | position): sorted, the candidates in ascending sample index.
  thread_local std::vector<std::uint64_t> by_sample;
  thread_local std::vector<float> xs, ys, zs, dist;
  thread_local std::vector<std::uint64_t> pick, chosen;
  by_sample.resize(candidates.size());
  for (std::size_t j = 0; j < candidates.size(); ++j)
    by_sample[j] = std::uint64_t(ix.sample[candidates[j]]) << 32 | candidates[j];
  std::sort(by_sample.begin(), by_sample.end());
  const std::size_t count = by_sample.size();
  const auto position = [&](std::size_t j) { return std::uint32_t(by_sample[j]); };
  xs.resize(count);
  ys.resize(count);
  zs.resize(count);
  for (std::size_t j = 0; j < count; ++j) {
    const float* p = ix.xyz.data() + 3 * std::size_t(position(j));
    xs[j] = p[0];
    ys[j] = p[1];
    zs[j] = p[2];
  }
  dist.resize(count);
  // The k-th distance of the previous query, a little enlarged: along a row it picks the few candidates to select
  // from without looking at the rest. The passes over the candidates have no branches: the distances (as
  // distance2 sums them), the kept keys (written always, advanced past only when kept), and the output, from the
  // kept keys, which stay in ascending rank while a copy of them is selected from.
  pick.resize(count + kKeepSlack);
  chosen.resize(count);
  float guess = std::numeric_limits<float>::infinity();
  const auto key = [&](std::size_t j) { return std::uint64_t(std::bit_cast<std::uint32_t>(dist[j])) << 32 | j; };
  for (std::size_t i = 0; i < at.size(); ++i) {
    const float* qi = q.data() + 3 * i;
    for (std::size_t j = 0; j < count; ++j) {
      const float tx = qi[0] - xs[j], ty = qi[1] - ys[j], tz = qi[2] - zs[j];
      float d = 0;
      d += tx * tx;
      d += ty * ty;
      d += tz * tz;
      dist[j] = d;
    }
    std::size_t kept = keep_within(dist.data(), count, guess, pick.data());
    if (kept < k) {
      for (std::size_t j = 0; j < count; ++j) pick[j] = key(j);
      kept = count;
    }
    std::copy_n(pick.begin(), kept, chosen.begin());
    const std::uint64_t kth = select_kth(std::span(chosen).first(kept), k);
    guess = std::bit_cast<float>(std::uint32_t(kth >> 32)) * 1.1f;
    const auto nearest = std::uint32_t(*std::min_element(chosen.begin(), chosen.begin() + std::ptrdiff_t(k)));
    Neighbours& o = out[i];
    o.index.resize(k + 1);
    o.dist2.resize(k + 1);
    std::size_t n = 0;
    for (std::size_t e = 0; e < kept; ++e) {
      const std::uint64_t kj = pick[e];
      const auto j = std::uint32_t(kj);
      o.index[n] = position(j);
      o.dist2[n] = dist[j];
      n += kj <= kth;
    }
    o.index.resize(k);
    o.dist2.resize(k);
    finish(at[i], qi, position(nearest), o, offsets, gap_cap);
  }
}

}  // namespace specula::brdf
