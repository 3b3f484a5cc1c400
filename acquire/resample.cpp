#include "acquire/resample.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "core/error.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

// |phi_o - phi_i| folded into [0, pi]: an isotropic BRDF depends on the azimuth difference only, and on its sign
// not at all.
double phi_diff(double phi_i, double phi_o) {
  double d = std::fmod(std::abs(phi_o - phi_i), 2 * pi);
  return d > pi ? 2 * pi - d : d;
}

struct Cloud {
  std::vector<double> xyz;  // n x 3
  std::size_t kdtree_get_point_count() const { return xyz.size() / 3; }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return xyz[3 * i + d]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3, std::size_t>;

}  // namespace

struct Resampler::Tree {
  Cloud cloud;
  std::unique_ptr<KdTree> index;
};

Mapping parse_mapping(std::string_view name) {
  if (name == "standard") return Mapping::standard;
  if (name == "marschner") return Mapping::marschner;
  if (name == "halfdiff") return Mapping::halfdiff;
  throw UsageError("--mapping '" + std::string(name) + "': use standard (M_s), marschner (M_m) or halfdiff (M_h)");
}

std::string_view mapping_name(Mapping m) {
  switch (m) {
    case Mapping::standard: return "standard";
    case Mapping::marschner: return "marschner";
    case Mapping::halfdiff: return "halfdiff";
  }
  return "?";
}

Weights parse_weights(std::string_view name) {
  if (name == "mean") return Weights::mean;
  if (name == "shepard") return Weights::shepard;
  throw UsageError("--weights '" + std::string(name) + "': use shepard (eqs 5.9-5.10) or mean");
}

Eigen::Vector3d map_angles(Mapping m, const brdf::StdAngles& a) {
  const double pd = phi_diff(a.phi_i, a.phi_o);
  switch (m) {
    case Mapping::standard: return {a.theta_i, a.theta_o, pd};
    case Mapping::marschner:
      return {std::sin(a.theta_i) * std::sin(a.theta_o), pd / pi, std::cos(a.theta_i) * std::cos(a.theta_o)};
    case Mapping::halfdiff: {
      const brdf::HalfDiff h = brdf::half_diff(brdf::StdAngles{a.theta_i, 0.0, a.theta_o, pd});
      return {h.theta_h, h.theta_d, phi_diff(0.0, h.phi_d) > pi / 2 ? pi - phi_diff(0.0, h.phi_d) : phi_diff(0.0, h.phi_d)};
    }
  }
  return {};
}

Resampler::Resampler(std::span<const double> angles, std::span<const float> values, std::size_t bands,
                     const ResampleOptions& o)
    : n_(angles.size() / 4), bands_(bands), o_(o), angles_(angles), values_(values) {
  if (o.k < 1 || o.k > 100000) throw UsageError("-k " + std::to_string(o.k) + ": give 1 to 100000 neighbours");
  if (!(o.power >= 0) || !std::isfinite(o.power)) throw UsageError("--power must be a finite number >= 0");
  if (!(o.max_gap > 0)) throw UsageError("the largest gap must be positive");
  if (bands == 0 || angles.size() % 4 != 0 || values.size() != n_ * bands)
    throw UsageError("resample: angles must be n x 4 and values n x bands");
  if (n_ == 0) throw InputError("no samples to resample");
  tree_ = std::make_unique<Tree>();
  tree_->cloud.xyz.resize(3 * n_);
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < static_cast<long long>(n_); ++i) {
    const double* a = angles.data() + 4 * i;
    const Eigen::Vector3d p = map_angles(o.mapping, {a[0], a[1], a[2], a[3]});
    for (int d = 0; d < 3; ++d) tree_->cloud.xyz[3 * std::size_t(i) + std::size_t(d)] = p[d];
  }
  tree_->index = std::make_unique<KdTree>(3, tree_->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
}

Resampler::~Resampler() = default;

void Resampler::neighbours(const brdf::StdAngles& at, std::vector<std::size_t>& index, std::vector<double>& dist2) const {
  const Eigen::Vector3d q = map_angles(o_.mapping, at);
  const std::size_t k = std::min(o_.k, n_);
  index.resize(k);
  dist2.resize(k);
  const std::size_t found = tree_->index->knnSearch(q.data(), k, index.data(), dist2.data());
  index.resize(found);
  dist2.resize(found);
}

bool Resampler::predict(const brdf::StdAngles& at, std::span<float> out) const {
  thread_local std::vector<std::size_t> index;
  thread_local std::vector<double> dist2;
  thread_local std::vector<double> acc;
  neighbours(at, index, dist2);
  if (index.empty()) return false;
  // Support: the nearest sample within max_gap in (theta_i, theta_o, phi_d), whatever the mapping.
  const double* a = angles_.data() + 4 * index[0];
  const double dt = a[0] - at.theta_i, dto = a[2] - at.theta_o, dp = phi_diff(a[1], a[3]) - phi_diff(at.phi_i, at.phi_o);
  if (std::sqrt(dt * dt + dto * dto + dp * dp) > o_.max_gap) return false;
  acc.assign(bands_, 0.0);
  double wsum = 0;
  // Shepard: w = 1 / d^p (eq 5.10); a sample at distance 0 takes all the weight.
  if (o_.weights == Weights::shepard && dist2[0] == 0) {
    for (std::size_t k = 0; k < bands_; ++k) out[k] = values_[index[0] * bands_ + k];
    return true;
  }
  for (std::size_t j = 0; j < index.size(); ++j) {
    const double w = o_.weights == Weights::mean ? 1.0 : std::pow(dist2[j], -0.5 * o_.power);
    const float* v = values_.data() + index[j] * bands_;
    for (std::size_t k = 0; k < bands_; ++k) acc[k] += w * double(v[k]);
    wsum += w;
  }
  for (std::size_t k = 0; k < bands_; ++k) out[k] = float(acc[k] / wsum);
  return true;
}

std::size_t Resampler::fill_grid(std::span<float> grid) const {
  const std::size_t cells = brdf::kMerlCells;
  if (grid.size() != bands_ * cells) throw UsageError("resample: the grid must hold bands x 90 x 90 x 180 values");
  std::size_t valid = 0;
#pragma omp parallel reduction(+ : valid)
  {
    std::vector<float> out(bands_);
#pragma omp for schedule(dynamic, 1024)
    for (long long c = 0; c < static_cast<long long>(cells); ++c) {
      const brdf::MerlCell cell = brdf::merl_cell(std::size_t(c));
      bool ok = brdf::merl_cell_valid(cell);
      if (ok) ok = predict(brdf::std_angles(brdf::merl_cell_centre(cell)), out);
      for (std::size_t k = 0; k < bands_; ++k) grid[k * cells + std::size_t(c)] = ok ? out[k] : -1.0f;
      valid += ok;
    }
  }
  return valid;
}

}  // namespace specula::acquire
