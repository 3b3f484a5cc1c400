#include "specula/core/brdf_resample.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <limits>
#include <numeric>
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
using KnnResult = nanoflann::KNNResultSet<float, std::uint32_t>;

// The points are cut into slabs along one axis and every slab gets its own tree, so that the trees are built on
// all threads. The number of slabs depends on the number of points only: the same trees, neighbours and ties
// for any thread count.
std::size_t slab_count(std::size_t n) { return std::clamp<std::size_t>(n >> 20, 1, 8); }

Eigen::Vector3f mapped(Mapping m, const IsoAngles& a) { return map_angles(m, a).cast<float>(); }

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

void SampleTree::nearest(const IsoAngles& at, std::size_t k, Neighbours& out, bool offsets) const {
  const Index& ix = *index_;
  const Eigen::Vector3f q = mapped(mapping_, at);
  k = std::min(k, n_);
  out.index.resize(k);
  out.dist2.resize(k);
  KnnResult result(k);
  result.init(out.index.data(), out.dist2.data());
  // The query's own slab first, then the others outwards while they can still hold a nearer point.
  const auto slabs = static_cast<std::ptrdiff_t>(ix.slabs.size());
  const float x = q[ix.axis];
  const std::ptrdiff_t own = std::upper_bound(ix.cuts.begin(), ix.cuts.end(), x) - ix.cuts.begin();
  auto search = [&](std::ptrdiff_t s) {
    const auto& slab = *ix.slabs[std::size_t(s)];
    if (slab.tree) slab.tree->findNeighbors(result, q.data(), nanoflann::SearchParams());
  };
  search(own);
  for (std::ptrdiff_t left = own - 1, right = own + 1; left >= 0 || right < slabs;) {
    const float gl = left >= 0 ? x - ix.slabs[std::size_t(left)]->high : std::numeric_limits<float>::infinity();
    const float gr = right < slabs ? ix.slabs[std::size_t(right)]->low - x : std::numeric_limits<float>::infinity();
    const bool go_left = gl <= gr;
    const float gap = go_left ? gl : gr;
    if (result.full() && gap * gap > result.worstDist()) break;
    search(go_left ? left-- : right++);
  }
  const std::size_t found = result.size();
  out.index.resize(found);
  out.dist2.resize(found);
  out.offset.resize(offsets ? 3 * found : 0);
  out.gap = std::numeric_limits<double>::infinity();
  if (found == 0) return;
  if (offsets)
    for (std::size_t j = 0; j < found; ++j)
      for (std::size_t d = 0; d < 3; ++d)
        out.offset[3 * j + d] = ix.xyz[3 * std::size_t(out.index[j]) + d] - q[Eigen::Index(d)];
  const float* p = ix.xyz.data() + 3 * std::size_t(out.index[0]);
  out.gap = config_distance(at, unmap(mapping_, Eigen::Vector3d(p[0], p[1], p[2])), mapping_is_reciprocal(mapping_));
  for (auto& i : out.index) i = ix.sample[i];
}

}  // namespace specula::brdf
