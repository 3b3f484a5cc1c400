#include "specula/codec/rgl_warp.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "specula/core/error.h"
#include "specula/core/nnls.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

// Largest i in [0, size - 2] with pred(i), or 0 (Mitsuba's and pbrt's FindInterval).
template <class Pred>
std::size_t find_interval(std::size_t size, Pred pred) {
  std::size_t first = 1, len = size - 2;
  while (len > 0) {
    const std::size_t half = len >> 1, middle = first + half;
    if (pred(middle)) {
      first = middle + 1;
      len -= half + 1;
    } else {
      len = half;
    }
  }
  const std::size_t i = first - 1;
  return std::min(i, size - 2);
}

double safe_sqrt(double v) { return std::sqrt(std::max(v, 0.0)); }

// The CDF at x in [0, 1] of the piecewise-linear density on n nodes uniform in [0, 1], as a row of weights on the
// node values.
Eigen::RowVectorXd cdf_weights(double x, std::size_t n) {
  const double h = 1.0 / double(n - 1), s = std::clamp(x, 0.0, 1.0) * double(n - 1);
  const std::size_t k = std::min(std::size_t(s), n - 2);
  const double t = s - double(k);
  Eigen::RowVectorXd r = Eigen::RowVectorXd::Zero(Eigen::Index(n));
  for (std::size_t m = 0; m < k; ++m) {
    r[Eigen::Index(m)] += h / 2;
    r[Eigen::Index(m + 1)] += h / 2;
  }
  r[Eigen::Index(k)] += h * (t - t * t / 2);
  r[Eigen::Index(k + 1)] += h * t * t / 2;
  return r;
}

// Piecewise-linear densities on `from` nodes uniform in [0, 1] as ones on n nodes: the non-negative values whose CDF
// is closest in least squares to the original's at 8 points per original interval. Prepared once per pair of sizes.
class CdfFit {
 public:
  CdfFit(std::size_t from, std::size_t n) : nnls_(gram(from, n)) {}
  std::vector<double> operator()(std::span<const double> values) const {
    const Eigen::VectorXd h = to_rhs_ * Eigen::Map<const Eigen::VectorXd>(values.data(), Eigen::Index(values.size()));
    std::vector<double> out(nnls_.k());
    nnls_.solve(h.data(), out.data());
    return out;
  }

 private:
  Eigen::MatrixXd gram(std::size_t from, std::size_t n) {
    const std::size_t points = (from - 1) * 8;
    Eigen::MatrixXd g = Eigen::MatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    to_rhs_ = Eigen::MatrixXd::Zero(Eigen::Index(n), Eigen::Index(from));
    for (std::size_t q = 0; q <= points; ++q) {
      const double x = double(q) / double(points);
      const Eigen::RowVectorXd r = cdf_weights(x, n);
      g.noalias() += r.transpose() * r;
      to_rhs_.noalias() += r.transpose() * cdf_weights(x, from);
    }
    return g;
  }
  Eigen::MatrixXd to_rhs_;  // n x from: the right-hand side of the normal equations from the original values
  GramNnls nnls_;
};

// Integral over [0, 1] of the piecewise-linear density on the nodes uniform in [0, 1].
double integral(std::span<const double> v) {
  double s = 0;
  for (std::size_t i = 0; i + 1 < v.size(); ++i) s += 0.5 * (v[i] + v[i + 1]);
  return s / double(v.size() - 1);
}

}  // namespace

Warp2D::Warp2D(std::span<const float> data, std::size_t width, std::size_t height,
               std::vector<std::vector<float>> params, bool density)
    : w_(width), h_(height), params_(std::move(params)), density_(density) {
  if (w_ < 2 || h_ < 2)
    throw UsageError("Warp2D: a grid needs at least 2 x 2 nodes, not " + std::to_string(w_) + " x " +
                     std::to_string(h_));
  if (params_.size() > 3) throw UsageError("Warp2D: at most 3 parameters");
  std::size_t slices = 1;
  param_stride_.assign(params_.size(), 0);
  for (std::size_t d = params_.size(); d-- > 0;) {
    if (params_[d].empty()) throw UsageError("Warp2D: parameter " + std::to_string(d) + " has no values");
    param_stride_[d] = params_[d].size() > 1 ? slices : 0;
    slices *= params_[d].size();
  }
  const std::size_t n = w_ * h_;
  if (data.size() != slices * n)
    throw UsageError("Warp2D: " + std::to_string(data.size()) + " values for " + std::to_string(slices) +
                     " slices of " + std::to_string(w_) + " x " + std::to_string(h_));
  data_.assign(data.begin(), data.end());
  if (!density_) return;
  marginal_.assign(slices * h_, 0.0f);
  conditional_.assign(slices * n, 0.0f);
  for (std::size_t s = 0; s < slices; ++s) {
    const float* in = data.data() + s * n;
    float* cond = conditional_.data() + s * n;
    float* marg = marginal_.data() + s * h_;
    for (std::size_t y = 0; y < h_; ++y) {
      double sum = 0;
      cond[y * w_] = 0;
      for (std::size_t x = 0; x + 1 < w_; ++x) {
        sum += 0.5 * (double(in[y * w_ + x]) + double(in[y * w_ + x + 1]));
        cond[y * w_ + x + 1] = float(sum);
      }
    }
    double sum = 0;
    marg[0] = 0;
    for (std::size_t y = 0; y + 1 < h_; ++y) {
      sum += 0.5 * (double(cond[(y + 1) * w_ - 1]) + double(cond[(y + 2) * w_ - 1]));
      marg[y + 1] = float(sum);
    }
    const float norm = 1.0f / marg[h_ - 1];
    for (std::size_t i = 0; i < n; ++i) cond[i] *= norm;
    for (std::size_t i = 0; i < h_; ++i) marg[i] *= norm;
    for (std::size_t i = 0; i < n; ++i) data_[s * n + i] = in[i] * norm;
  }
}

Warp2D::Corners Warp2D::corners(std::span<const double> param, std::size_t dims) const {
  Corners c;
  c.n = 1;
  c.slice[0] = 0;
  c.weight[0] = 1;
  for (std::size_t d = 0; d < dims; ++d) {
    const auto& v = params_[d];
    if (v.size() == 1) continue;
    const double p = d < param.size() ? param[d] : 0.0;
    const std::size_t i = find_interval(v.size(), [&](std::size_t k) { return double(v[k]) < p; });
    const double p0 = v[i], p1 = v[i + 1];
    const double w1 = std::clamp((p - p0) / (p1 - p0), 0.0, 1.0), w0 = 1 - w1;
    for (int k = 0; k < c.n; ++k) {
      c.slice[std::size_t(c.n + k)] = c.slice[std::size_t(k)] + param_stride_[d] * (i + 1);
      c.weight[std::size_t(c.n + k)] = c.weight[std::size_t(k)] * w1;
      c.slice[std::size_t(k)] += param_stride_[d] * i;
      c.weight[std::size_t(k)] *= w0;
    }
    c.n *= 2;
  }
  return c;
}

double Warp2D::lookup(const std::vector<float>& a, std::size_t stride, std::size_t index, const Corners& c) const {
  double v = 0;
  for (int k = 0; k < c.n; ++k) v += c.weight[std::size_t(k)] * double(a[c.slice[std::size_t(k)] * stride + index]);
  return v;
}

Warp2D::Patch Warp2D::patch(double x, double y) const {
  x = std::clamp(x, 0.0, 1.0) * double(w_ - 1);
  y = std::clamp(y, 0.0, 1.0) * double(h_ - 1);
  Patch p;
  p.ix = std::min(std::size_t(x), w_ - 2);
  p.iy = std::min(std::size_t(y), h_ - 2);
  p.fx = x - double(p.ix);
  p.fy = y - double(p.iy);
  return p;
}

double Warp2D::eval(double x, double y, std::span<const double> param) const {
  const Corners c = corners(param, params_.size());
  const auto [ix, iy, fx, fy] = patch(x, y);
  const std::size_t n = w_ * h_, i = ix + iy * w_;
  const double v00 = lookup(data_, n, i, c), v10 = lookup(data_, n, i + 1, c), v01 = lookup(data_, n, i + w_, c),
               v11 = lookup(data_, n, i + w_ + 1, c);
  const double v = (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11);
  return density_ ? v * double(w_ - 1) * double(h_ - 1) : v;
}

void Warp2D::eval_last(double x, double y, std::span<const double> param, std::span<double> out) const {
  if (density_ || params_.empty()) throw UsageError("Warp2D::eval_last: needs a value table with parameters");
  const std::size_t last = params_.size() - 1;
  if (out.size() != params_[last].size())
    throw UsageError("Warp2D::eval_last: out holds " + std::to_string(out.size()) + " values, the last parameter " +
                     std::to_string(params_[last].size()));
  const Corners c = corners(param, last);
  const auto [ix, iy, fx, fy] = patch(x, y);
  const std::size_t n = w_ * h_, step = param_stride_[last] * n;
  for (std::size_t k = 0; k < out.size(); ++k) {
    const std::size_t i = ix + iy * w_ + k * step;
    const double v00 = lookup(data_, n, i, c), v10 = lookup(data_, n, i + 1, c), v01 = lookup(data_, n, i + w_, c),
                 v11 = lookup(data_, n, i + w_ + 1, c);
    out[k] = (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11);
  }
}

WarpStencil Warp2D::stencil(double x, double y, std::span<const double> param, std::size_t dims) const {
  if (density_) throw UsageError("Warp2D::stencil: a density table's values are normalised copies of its data");
  const Corners c = corners(param, std::min(dims, params_.size()));
  const auto [ix, iy, fx, fy] = patch(x, y);
  const std::size_t n = w_ * h_, i = ix + iy * w_;
  const std::size_t node[4] = {i, i + 1, i + w_, i + w_ + 1};
  const double bilinear[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  WarpStencil s;
  for (int k = 0; k < c.n; ++k)
    for (int q = 0; q < 4; ++q) {
      s.index[std::size_t(s.n)] = c.slice[std::size_t(k)] * n + node[q];
      s.weight[std::size_t(s.n++)] = c.weight[std::size_t(k)] * bilinear[q];
    }
  return s;
}

WarpPoint Warp2D::sample(double x, double y, std::span<const double> param) const {
  if (!density_) throw UsageError("Warp2D::sample: the table was built without a CDF");
  const Corners c = corners(param, params_.size());
  constexpr double eps = std::numeric_limits<float>::epsilon() / 2, one_minus = 1.0 - eps;
  x = std::clamp(x, eps, one_minus);
  y = std::clamp(y, eps, one_minus);
  const std::size_t n = w_ * h_;
  auto marginal = [&](std::size_t k) { return lookup(marginal_, h_, k, c); };
  const std::size_t row = find_interval(h_, [&](std::size_t k) { return marginal(k) < y; });
  y -= marginal(row);
  const double r0 = lookup(conditional_, n, row * w_ + w_ - 1, c),
               r1 = lookup(conditional_, n, row * w_ + 2 * w_ - 1, c);
  bool flat = std::abs(r0 - r1) < 1e-4 * (r0 + r1);
  y = flat ? 2 * y / (r0 + r1) : (r0 - safe_sqrt(r0 * r0 - 2 * y * (r0 - r1))) / (r0 - r1);
  x *= (1 - y) * r0 + y * r1;
  auto conditional = [&](std::size_t k) {
    return (1 - y) * lookup(conditional_, n, row * w_ + k, c) + y * lookup(conditional_, n, row * w_ + w_ + k, c);
  };
  const std::size_t col = find_interval(w_, [&](std::size_t k) { return conditional(k) < x; });
  x -= conditional(col);
  const std::size_t i = row * w_ + col;
  const double v00 = lookup(data_, n, i, c), v10 = lookup(data_, n, i + 1, c), v01 = lookup(data_, n, i + w_, c),
               v11 = lookup(data_, n, i + w_ + 1, c);
  const double c0 = (1 - y) * v00 + y * v01, c1 = (1 - y) * v10 + y * v11;
  flat = std::abs(c0 - c1) < 1e-4 * (c0 + c1);
  x = flat ? 2 * x : c0 - safe_sqrt(c0 * c0 - 2 * x * (c0 - c1));
  const double divisor = flat ? c0 + c1 : c0 - c1;
  if (divisor != 0) x /= divisor;
  return {(double(col) + x) / double(w_ - 1), (double(row) + y) / double(h_ - 1),
          ((1 - x) * c0 + x * c1) * double(w_ - 1) * double(h_ - 1)};
}

WarpPoint Warp2D::invert(double x, double y, std::span<const double> param) const {
  if (!density_) throw UsageError("Warp2D::invert: the table was built without a CDF");
  const Corners c = corners(param, params_.size());
  const Patch p = patch(x, y);
  const std::size_t ix = p.ix, iy = p.iy;
  x = p.fx;
  y = p.fy;
  const std::size_t n = w_ * h_, i = ix + iy * w_;
  const double v00 = lookup(data_, n, i, c), v10 = lookup(data_, n, i + 1, c), v01 = lookup(data_, n, i + w_, c),
               v11 = lookup(data_, n, i + w_ + 1, c);
  const double c0 = (1 - y) * v00 + y * v01, c1 = (1 - y) * v10 + y * v11, pdf = (1 - x) * c0 + x * c1;
  x *= c0 + 0.5 * x * (c1 - c0);
  x += (1 - y) * lookup(conditional_, n, i, c) + y * lookup(conditional_, n, i + w_, c);
  const double r0 = lookup(conditional_, n, iy * w_ + w_ - 1, c), r1 = lookup(conditional_, n, iy * w_ + 2 * w_ - 1, c);
  x /= (1 - y) * r0 + y * r1;
  y *= r0 + 0.5 * y * (r1 - r0);
  y += lookup(marginal_, h_, iy, c);
  return {x, y, pdf * double(w_ - 1) * double(h_ - 1)};
}

std::vector<float> resample_density(std::span<const float> data, std::size_t width, std::size_t height,
                                    std::size_t new_width, std::size_t new_height) {
  if (width < 2 || height < 2 || new_width < 2 || new_height < 2)
    throw UsageError("resample_density: a table needs at least 2 x 2 nodes");
  const std::size_t n = width * height, slices = data.size() / n;
  if (data.size() != slices * n)
    throw UsageError("resample_density: " + std::to_string(data.size()) + " values are not slices of " +
                     std::to_string(width) + " x " + std::to_string(height));
  if (new_width == width && new_height == height) return {data.begin(), data.end()};
  std::optional<CdfFit> columns, rows;  // for the sides that change
  if (new_width != width) columns.emplace(width, new_width);
  if (new_height != height) rows.emplace(height, new_height);
  std::vector<float> out(slices * new_width * new_height);
  parallel_for(slices, [&](std::size_t s) {
    const float* in = data.data() + s * n;
    std::vector<double> row(width), totals(height);
    for (std::size_t y = 0; y < height; ++y) {
      for (std::size_t x = 0; x < width; ++x) row[x] = in[y * width + x];
      totals[y] = integral(row);
    }
    if (rows) totals = (*rows)(totals);
    for (std::size_t j = 0; j < new_height; ++j) {
      std::size_t r = j;  // the original interpolant at the new row's v: rows r and r + 1 blended by t
      double t = 0;
      if (rows) {
        const double v = double(j) / double(new_height - 1) * double(height - 1);
        r = std::min(std::size_t(v), height - 2);
        t = v - double(r);
      }
      for (std::size_t x = 0; x < width; ++x)
        row[x] = (1 - t) * in[r * width + x] + (t > 0 ? t * in[(r + 1) * width + x] : 0.0);
      const std::vector<double> fitted = columns ? (*columns)(row) : row;
      const double have = integral(fitted), scale = have > 0 ? totals[j] / have : 0.0;
      for (std::size_t i = 0; i < new_width; ++i) out[(s * new_height + j) * new_width + i] = float(fitted[i] * scale);
    }
  });
  return out;
}

}  // namespace specula::codec
