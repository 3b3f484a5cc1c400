// Variable-projection fit of the microfacet model (acquire/model_fit.h) to per-cell sample means, with Huber IRLS.
#include "specula/acquire/model_fit.h"

#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "specula/core/error.h"
#include "specula/core/nnls.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

using std::numbers::pi;

struct CellDirs {
  Eigen::Vector3d wi, wo;
};

CellDirs cell_dirs(std::uint32_t valid_index) {
  CellDirs d;
  brdf::directions(brdf::merl_cell_centre(brdf::merl_cell(valid_cells()[valid_index])), d.wi, d.wo);
  return d;
}

// Shape parameters <-> unconstrained LM variables: log alpha, then logit F0 (Schlick) or log(eta - 1).
LobeShape decode(FresnelKind f, double log_alpha, double q) {
  LobeShape s;
  s.alpha = std::exp(std::clamp(log_alpha, std::log(1e-3), std::log(2.0)));
  q = std::clamp(q, -30.0, 30.0);
  s.fresnel = f == FresnelKind::schlick ? 1 / (1 + std::exp(-q)) : 1 + std::exp(q);
  return s;
}

std::vector<LobeShape> decode(FresnelKind f, const Eigen::VectorXd& x) {
  std::vector<LobeShape> out;
  for (Eigen::Index j = 0; j + 1 < x.size(); j += 2) out.push_back(decode(f, x[j], x[j + 1]));
  return out;
}

double encode_fresnel(FresnelKind f, double v) {
  return f == FresnelKind::schlick ? std::log(v / (1 - v)) : std::log(v - 1);
}

// The design matrix: per cell 1/pi, then each lobe of unit albedo.
Eigen::MatrixXd design(const std::vector<CellDirs>& dirs, const ModelFitOptions& o, const std::vector<LobeShape>& s) {
  Eigen::MatrixXd x(Eigen::Index(dirs.size()), Eigen::Index(1 + s.size()));
  parallel_for(
      dirs.size(),
      [&](std::size_t i) {
        const auto r = Eigen::Index(i);
        x(r, 0) = 1 / pi;
        for (std::size_t j = 0; j < s.size(); ++j)
          x(r, Eigen::Index(1 + j)) = microfacet_lobe(o.kind, s[j], dirs[i].wi, dirs[i].wo);
      },
      4096);
  return x;
}

// argmin_{a >= 0} sum_i w_i (x_i a - y_i)^2; the sums in cell order (independent of the thread count).
Eigen::VectorXd weighted_nnls(const Eigen::MatrixXd& x, const Eigen::Ref<const Eigen::VectorXd>& y,
                              const Eigen::Ref<const Eigen::VectorXd>& w) {
  const Eigen::Index k = x.cols();
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(k, k);
  Eigen::VectorXd h = Eigen::VectorXd::Zero(k);
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const auto row = x.row(i);
    g.noalias() += w[i] * row.transpose() * row;
    h.noalias() += w[i] * y[i] * row.transpose();
  }
  Eigen::VectorXd a(k);
  GramNnls(g).solve(h.data(), a.data());
  return a;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// A floor for the relative residual's scale: 1 % of the median positive value of the signal.
double scale_floor(const Eigen::Ref<const Eigen::VectorXd>& y) {
  std::vector<double> pos;
  for (const double v : y)
    if (v > 0) pos.push_back(v);
  return std::max(1e-2 * median(std::move(pos)), 1e-9);
}

// Huber IRLS weights of one signal: the relative residual r_i = sqrt(n_i) (y_i - m_i) / s_i with s_i = max(m_i,
// floor) (m = y in the first round: all residuals 0, weights n_i / s_i^2); w_i = n_i h_i / s_i^2, h_i = min(1,
// c sigma / |r_i|), sigma = 1.4826 median |r|. Returns the fraction with h_i < 1.
double huber_weights(const Eigen::Ref<const Eigen::VectorXd>& y, const Eigen::Ref<const Eigen::VectorXd>& m,
                     const std::vector<double>& count, double floor, double huber, Eigen::Ref<Eigen::VectorXd> w) {
  const Eigen::Index n = y.size();
  std::vector<double> r(std::size_t(n), 0.0);
  for (Eigen::Index i = 0; i < n; ++i)
    r[std::size_t(i)] = std::abs(std::sqrt(count[std::size_t(i)]) * (y[i] - m[i]) / std::max(m[i], floor));
  const double cut = huber * 1.4826 * median(r);
  std::size_t down = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double s = std::max(m[i], floor), ri = r[std::size_t(i)];
    const double h = ri > cut && cut > 0 ? cut / ri : 1.0;
    down += h < 1;
    w[i] = count[std::size_t(i)] * h / (s * s);
  }
  return n ? double(down) / double(n) : 0.0;
}

// The variable-projection residual for LM: for shape variables x, the albedos of every channel by weighted NNLS,
// and the weighted residuals sqrt(w_ic) (X_i a_c - y_ic), channel by channel.
struct ShapeFunctor {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;

  const std::vector<CellDirs>* dirs;
  const Eigen::MatrixXd* y;  // cells x channels
  const Eigen::MatrixXd* w;  // cells x channels
  const ModelFitOptions* o;
  Eigen::Index n_inputs;
  std::size_t* evaluations;

  int inputs() const { return int(n_inputs); }
  int values() const { return int(y->size()); }
  // The albedos (lobes + 1 x channels) and the channel model (cells x channels) at x.
  Eigen::MatrixXd solve(const Eigen::VectorXd& x, Eigen::MatrixXd* model) const {
    const Eigen::MatrixXd d = design(*dirs, *o, decode(o->kind.fresnel, x));
    Eigen::MatrixXd a(d.cols(), y->cols());
    for (Eigen::Index c = 0; c < y->cols(); ++c) a.col(c) = weighted_nnls(d, y->col(c), w->col(c));
    *model = d * a;
    ++*evaluations;
    return a;
  }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    Eigen::MatrixXd m;
    solve(x, &m);
    f = (w->array().sqrt() * (m - *y).array()).reshaped();
    return 0;
  }
};

// The cells the shape fit sees: all when there are at most o.shape_cells; otherwise every s-th of the bright cells
// (above 3x the median brightness: the lobes) and every t-th of the rest, each standing for s or t cells.
std::vector<std::pair<std::size_t, double>> shape_subset(const std::vector<double>& brightness, std::size_t budget) {
  std::vector<std::pair<std::size_t, double>> out;
  const std::size_t n = brightness.size();
  if (n <= budget) {
    for (std::size_t i = 0; i < n; ++i) out.emplace_back(i, 1.0);
    return out;
  }
  const double bright = 3 * median(brightness);
  std::vector<std::size_t> hi, lo;
  for (std::size_t i = 0; i < n; ++i) (brightness[i] > bright ? hi : lo).push_back(i);
  const std::size_t s = std::max<std::size_t>(1, (hi.size() + budget / 2 - 1) / (budget / 2));
  const std::size_t left = budget - (hi.size() + s - 1) / s;
  const std::size_t t = std::max<std::size_t>(1, (lo.size() + left - 1) / std::max<std::size_t>(left, 1));
  for (std::size_t i = 0; i < hi.size(); i += s) out.emplace_back(hi[i], double(s));
  for (std::size_t i = 0; i < lo.size(); i += t) out.emplace_back(lo[i], double(t));
  std::sort(out.begin(), out.end());
  return out;
}

// The shape fit's data: the bands averaged in groups (channels) at the subset's cells.
struct ShapeData {
  std::vector<CellDirs> dirs;
  Eigen::MatrixXd y, w;
  std::vector<double> count;
  std::vector<double> floor;
};

ShapeData shape_data(const PriorObservations& obs, std::size_t bands, const ModelFitOptions& o) {
  const std::size_t n = obs.cell.size(), ch = std::min(o.shape_channels, bands);
  std::vector<double> brightness(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t b = 0; b < bands; ++b) brightness[i] += obs.values[i * bands + b];
  const auto subset = shape_subset(brightness, o.shape_cells);
  ShapeData d;
  d.dirs.resize(subset.size());
  d.y = Eigen::MatrixXd::Zero(Eigen::Index(subset.size()), Eigen::Index(ch));
  d.w.resize(d.y.rows(), d.y.cols());
  d.count.resize(subset.size());
  for (std::size_t r = 0; r < subset.size(); ++r) {
    const std::size_t i = subset[r].first;
    d.dirs[r] = cell_dirs(obs.cell[i]);
    d.count[r] = obs.weight[i] * subset[r].second;
    for (std::size_t b = 0; b < bands; ++b) {
      const std::size_t c = b * ch / bands, first = (c * bands + ch - 1) / ch, last = ((c + 1) * bands + ch - 1) / ch;
      d.y(Eigen::Index(r), Eigen::Index(c)) += obs.values[i * bands + b] / double(last - first);
    }
  }
  for (Eigen::Index c = 0; c < d.y.cols(); ++c) d.floor.push_back(scale_floor(d.y.col(c)));
  return d;
}

// IRLS rounds of LM over the shape variables x (updated), starting from the weights in d.w.
void irls_shapes(ShapeData& d, const ModelFitOptions& o, Eigen::VectorXd& x, std::size_t& evaluations) {
  ShapeFunctor fun{&d.dirs, &d.y, &d.w, &o, x.size(), &evaluations};
  for (std::size_t round = 0; round < o.irls_rounds; ++round) {
    Eigen::NumericalDiff<ShapeFunctor> diff(fun);
    Eigen::LevenbergMarquardt<Eigen::NumericalDiff<ShapeFunctor>, double> lm(diff);
    lm.parameters.maxfev = 60 * int(x.size() + 1);
    lm.parameters.xtol = 1e-7;
    const Eigen::VectorXd before = x;
    lm.minimize(x);
    if (round > 0 && (x - before).cwiseAbs().maxCoeff() < 1e-5) break;  // the weights no longer move the shapes
    Eigen::MatrixXd m;
    fun.solve(x, &m);
    for (Eigen::Index c = 0; c < d.y.cols(); ++c)
      huber_weights(d.y.col(c), m.col(c), d.count, d.floor[std::size_t(c)], o.huber, d.w.col(c));
  }
}

// The start among `candidates` (shape variables) with the least cost under the current weights.
Eigen::VectorXd best_start(const ShapeData& d, const ModelFitOptions& o, const std::vector<Eigen::VectorXd>& candidates,
                           std::size_t& evaluations) {
  const ShapeFunctor fun{&d.dirs, &d.y, &d.w, &o, candidates.front().size(), &evaluations};
  double best = std::numeric_limits<double>::infinity();
  Eigen::VectorXd out = candidates.front();
  for (const Eigen::VectorXd& x : candidates) {
    Eigen::VectorXd f;
    fun(x, f);
    if (f.squaredNorm() < best) best = f.squaredNorm(), out = x;
  }
  return out;
}

// The shapes of o.lobes lobes: one lobe from a coarse roughness search, then (for two) a second lobe started
// narrower or broader than the first.
Eigen::VectorXd fit_shapes(ShapeData& d, const ModelFitOptions& o, std::size_t& evaluations) {
  for (Eigen::Index c = 0; c < d.y.cols(); ++c)
    huber_weights(d.y.col(c), d.y.col(c), d.count, d.floor[std::size_t(c)], o.huber, d.w.col(c));
  const double q0 = encode_fresnel(o.kind.fresnel, o.kind.fresnel == FresnelKind::schlick ? 0.04 : 1.5);
  std::vector<Eigen::VectorXd> starts;
  for (const double a : {0.02, 0.05, 0.1, 0.2, 0.4}) starts.push_back(Eigen::Vector2d(std::log(a), q0));
  Eigen::VectorXd x = best_start(d, o, starts, evaluations);
  irls_shapes(d, o, x, evaluations);
  if (o.lobes == 1) return x;
  starts.clear();
  for (const double f : {0.25, 4.0}) {
    Eigen::VectorXd x2(4);
    x2 << x[0], x[1], x[0] + std::log(f), q0;
    starts.push_back(x2);
  }
  x = best_start(d, o, starts, evaluations);
  irls_shapes(d, o, x, evaluations);
  return x;
}

}  // namespace

MicrofacetBrdf fit_model(const PriorObservations& obs, const WavelengthGrid& bands, const ModelFitOptions& o,
                         ModelFitReport* report) {
  const std::size_t b = bands.size(), n = obs.cell.size();
  if (o.lobes < 1 || o.lobes > 2) throw UsageError("model fit: lobes must be 1 or 2, not " + std::to_string(o.lobes));
  if (o.shape_channels == 0 || o.shape_cells < 100 || o.irls_rounds == 0 || !(o.huber > 0))
    throw UsageError("model fit: shape_channels and irls_rounds must be >= 1, shape_cells >= 100, huber > 0");
  if (b == 0 || obs.values.size() != n * b || obs.weight.size() != n)
    throw UsageError("model fit: observations of the wrong size for " + std::to_string(b) + " bands");
  if (n < 4 * (1 + o.lobes))
    throw InputError("model fit: only " + std::to_string(n) + " cells hold samples; need at least " +
                     std::to_string(4 * (1 + o.lobes)));
  ModelFitReport rep;
  rep.observed_cells = n;
  ShapeData d = shape_data(obs, b, o);
  rep.shape_cells = d.dirs.size();
  const std::vector<LobeShape> shapes = decode(o.kind.fresnel, fit_shapes(d, o, rep.evaluations));
  // The albedos per band on every observed cell, with their own IRLS rounds.
  std::vector<CellDirs> dirs(n);
  parallel_for(
      n, [&](std::size_t i) { dirs[i] = cell_dirs(obs.cell[i]); }, 4096);
  const Eigen::MatrixXd x = design(dirs, o, shapes);
  std::vector<double> count(obs.weight.begin(), obs.weight.end());
  Eigen::MatrixXd albedo(x.cols(), Eigen::Index(b));
  std::vector<double> down(b), sq(b);
  parallel_for(b, [&](std::size_t k) {
    Eigen::VectorXd y = Eigen::VectorXd::Zero(Eigen::Index(n)), w = y;
    for (std::size_t i = 0; i < n; ++i) y[Eigen::Index(i)] = obs.values[i * b + k];
    const double floor = scale_floor(y);
    Eigen::VectorXd m = y;
    for (std::size_t round = 0; round <= o.irls_rounds; ++round) {
      down[k] = huber_weights(y, m, count, floor, o.huber, w);
      if (round == o.irls_rounds) break;
      albedo.col(Eigen::Index(k)) = weighted_nnls(x, y, w);
      m = x * albedo.col(Eigen::Index(k));
    }
    for (std::size_t i = 0; i < n; ++i) {
      const double r = (y[Eigen::Index(i)] - m[Eigen::Index(i)]) / std::max(m[Eigen::Index(i)], floor);
      sq[k] += count[i] * r * r;
    }
  });
  double total = 0, weight = 0;
  for (std::size_t k = 0; k < b; ++k) rep.downweighted += down[k] / double(b), total += sq[k];
  for (const double c : count) weight += c;
  rep.relative_rms = std::sqrt(total / (weight * double(b)));
  if (report) *report = rep;
  std::vector<Eigen::VectorXd> specular;
  for (std::size_t j = 0; j < shapes.size(); ++j) specular.push_back(albedo.row(Eigen::Index(1 + j)).transpose());
  return MicrofacetBrdf(bands, o.kind, albedo.row(0).transpose(), shapes, std::move(specular));
}

}  // namespace specula::acquire
