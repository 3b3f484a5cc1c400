#include "specula/acquire/calibrate.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <string>

#include "specula/core/error.h"

namespace specula::acquire {

using std::numbers::pi;

SimplexResult nelder_mead(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x0,
                          const Eigen::VectorXd& step, int max_iterations, double tol) {
  const Eigen::Index n = x0.size();
  if (n == 0 || step.size() != n) throw UsageError("nelder_mead: give a start and one step per coordinate");
  std::vector<Eigen::VectorXd> p(std::size_t(n + 1), x0);
  std::vector<double> v(std::size_t(n + 1));
  for (Eigen::Index i = 0; i < n; ++i) p[std::size_t(i + 1)][i] += step[i];
  for (std::size_t i = 0; i < p.size(); ++i) v[i] = f(p[i]);
  std::vector<std::size_t> order(p.size());
  SimplexResult r;
  for (r.iterations = 0; r.iterations < max_iterations; ++r.iterations) {
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
    const std::size_t best = order.front(), worst = order.back(), second = order[order.size() - 2];
    if (std::abs(v[worst] - v[best]) <= tol * (std::abs(v[best]) + tol)) {
      double size = 0;
      for (const auto& q : p) size = std::max(size, (q - p[best]).cwiseAbs().cwiseQuotient(step.cwiseAbs()).maxCoeff());
      if (size < 1e-6) {
        r.converged = true;
        break;
      }
    }
    Eigen::VectorXd centroid = Eigen::VectorXd::Zero(n);
    for (std::size_t i : order)
      if (i != worst) centroid += p[i];
    centroid /= double(n);
    const Eigen::VectorXd xr = centroid + (centroid - p[worst]);
    const double fr = f(xr);
    if (fr < v[best]) {
      const Eigen::VectorXd xe = centroid + 2 * (centroid - p[worst]);
      const double fe = f(xe);
      if (fe < fr)
        p[worst] = xe, v[worst] = fe;
      else
        p[worst] = xr, v[worst] = fr;
      continue;
    }
    if (fr < v[second]) {
      p[worst] = xr, v[worst] = fr;
      continue;
    }
    const bool outside = fr < v[worst];
    const Eigen::VectorXd xc = outside ? Eigen::VectorXd(centroid + 0.5 * (xr - centroid))
                                       : Eigen::VectorXd(centroid + 0.5 * (p[worst] - centroid));
    const double fc = f(xc);
    if (fc < (outside ? fr : v[worst])) {
      p[worst] = xc, v[worst] = fc;
      continue;
    }
    for (std::size_t i = 0; i < p.size(); ++i)
      if (i != best) p[i] = p[best] + 0.5 * (p[i] - p[best]), v[i] = f(p[i]);
  }
  const auto it = std::min_element(v.begin(), v.end());
  r.x = p[std::size_t(it - v.begin())];
  r.value = *it;
  return r;
}

namespace {

// Gaussian blur (sigma 1 px, radius 3), separable, clamped at the borders.
GreyImage blur(const GreyImage& in) {
  const int W = in.width, H = in.height;
  std::array<double, 7> k{};
  double s = 0;
  for (int i = -3; i <= 3; ++i) s += (k[std::size_t(i + 3)] = std::exp(-0.5 * i * i));
  for (double& x : k) x /= s;
  GreyImage tmp = in, out = in;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      double a = 0;
      for (int i = -3; i <= 3; ++i) a += k[std::size_t(i + 3)] * in.at(std::clamp(u + i, 0, W - 1), v);
      tmp.value[std::size_t(v * W + u)] = float(a);
    }
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      double a = 0;
      for (int i = -3; i <= 3; ++i) a += k[std::size_t(i + 3)] * tmp.at(u, std::clamp(v + i, 0, H - 1));
      out.value[std::size_t(v * W + u)] = float(a);
    }
  return out;
}

// Bilinear interpolation at image position (x, y) with pixel centres at half-integers; 0 outside.
double bilinear(const GreyImage& g, double x, double y) {
  const double fx = x - 0.5, fy = y - 0.5;
  const int u = int(std::floor(fx)), v = int(std::floor(fy));
  if (u < 0 || v < 0 || u + 1 >= g.width || v + 1 >= g.height) return 0;
  const double a = fx - u, b = fy - v;
  return (1 - a) * (1 - b) * g.at(u, v) + a * (1 - b) * g.at(u + 1, v) + (1 - a) * b * g.at(u, v + 1) +
         a * b * g.at(u + 1, v + 1);
}

}  // namespace

Circle detect_circle(const GreyImage& s, int n) {
  const int W = s.width, H = s.height;
  if (W < 8 || H < 8 || s.value.size() != std::size_t(W) * std::size_t(H))
    throw UsageError("detect_circle: image too small or of the wrong size");
  std::vector<float> sorted = s.value;
  std::sort(sorted.begin(), sorted.end());
  const double dark = sorted[sorted.size() / 100], bright = sorted[sorted.size() * 9 / 10];
  if (!(bright > 2 * dark + 10))
    throw InputError("silhouette: no dark sphere on a bright board (the image is almost uniform)");
  const double threshold = 0.5 * (dark + bright);
  double area = 0, sx = 0, sy = 0;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u)
      if (s.at(u, v) < threshold) area += 1, sx += u + 0.5, sy += v + 0.5;
  if (area < 20) throw InputError("silhouette: no dark sphere on a bright board (fewer than 20 dark pixels)");
  Circle c{sx / area, sy / area, std::sqrt(area / pi)};
  const GreyImage b = blur(s);
  GreyImage grad = b;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const double gx = 0.5 * (b.at(std::min(u + 1, W - 1), v) - b.at(std::max(u - 1, 0), v));
      const double gy = 0.5 * (b.at(u, std::min(v + 1, H - 1)) - b.at(u, std::max(v - 1, 0)));
      grad.value[std::size_t(v * W + u)] = float(std::hypot(gx, gy));
    }
  // Eq 5.1; more points than the reference's 32 sharpen the optimum when the circle is large.
  const int points = std::max(n, int(std::ceil(2 * pi * c.r / 2)));
  auto objective = [&](const Eigen::VectorXd& x) {
    double sum = 0;
    for (int i = 1; i <= points; ++i) {
      const double a = 2 * pi * i / points;
      sum += bilinear(grad, x[0] + x[2] * std::sin(a), x[1] + x[2] * std::cos(a));
    }
    return -sum / points;
  };
  const SimplexResult r =
      nelder_mead(objective, Eigen::Vector3d(c.cx, c.cy, c.r), Eigen::Vector3d(1, 1, 1), 4000, 1e-12);
  return {r.x[0], r.x[1], r.x[2]};
}

bool Sphere::hit(const Eigen::Vector3d& d, double& t) const {
  const double b = d.dot(centre), disc = b * b - centre.squaredNorm() + radius * radius;
  if (disc <= 0) return false;
  t = b - std::sqrt(disc);
  return t > 0;
}

Sphere fit_sphere(const Circle& circle, const Pinhole& camera, double radius, int width, int height) {
  if (!(radius > 0) || !(camera.focal > 0) || !(circle.r > 0))
    throw UsageError("fit_sphere: radius, focal length and circle must be positive");
  // The cone through the circle: its axis through the circle's centre, its half-angle from the radius.
  const Eigen::Vector3d axis = camera.ray(circle.cx, circle.cy);
  const double half = std::atan(circle.r / camera.focal);
  const double distance = radius / std::sin(half);
  const int u0 = std::max(0, int(circle.cx - circle.r - 4)), u1 = std::min(width, int(circle.cx + circle.r + 5));
  const int v0 = std::max(0, int(circle.cy - circle.r - 4)), v1 = std::min(height, int(circle.cy + circle.r + 5));
  // Fractional coverage of each pixel by the circle's disc and by the traced sphere, 4 x 4 samples.
  auto coverage = [&](int u, int v, auto&& inside) {
    int k = 0;
    for (int sy = 0; sy < 4; ++sy)
      for (int sx = 0; sx < 4; ++sx) k += inside(u + (sx + 0.5) / 4, v + (sy + 0.5) / 4);
    return k / 16.0;
  };
  // Only a ring of pixels around the circle can disagree for spheres near the start: XOR is summed there.
  std::vector<std::pair<int, int>> ring;
  std::vector<double> disc;
  for (int v = v0; v < v1; ++v)
    for (int u = u0; u < u1; ++u) {
      if (std::abs(std::hypot(u + 0.5 - circle.cx, v + 0.5 - circle.cy) - circle.r) > 4) continue;
      ring.emplace_back(u, v);
      disc.push_back(
          coverage(u, v, [&](double x, double y) { return std::hypot(x - circle.cx, y - circle.cy) < circle.r; }));
    }
  auto objective = [&](const Eigen::VectorXd& c) {
    const Sphere s{Eigen::Vector3d(c[0], c[1], c[2]), radius};
    double sum = 0;
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const double traced = coverage(ring[i].first, ring[i].second, [&](double x, double y) {
        double t;
        return s.hit(camera.ray(x, y), t);
      });
      sum += std::abs(traced - disc[i]);
    }
    return sum;
  };
  const Eigen::Vector3d start = distance * axis;
  const double step = 0.2 * radius;
  const SimplexResult r = nelder_mead(objective, start, Eigen::Vector3d(step, step, 4 * step), 600, 1e-9);
  return {Eigen::Vector3d(r.x[0], r.x[1], r.x[2]), radius};
}

Eigen::Vector3d light_direction(const GreyImage& m, const Pinhole& camera, const Sphere& sphere, double light_distance,
                                double* confidence) {
  const int W = m.width, H = m.height;
  double best = -1;
  int bu = -1, bv = -1;
  for (int v = 1; v + 1 < H; ++v)
    for (int u = 1; u + 1 < W; ++u) {
      double t;
      if (!sphere.hit(camera.ray(u + 0.5, v + 0.5), t)) continue;
      double s = 0;
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) s += m.at(u + du, v + dv);
      if (s > best) best = s, bu = u, bv = v;
    }
  if (bu < 0) throw InputError("mirror image: the sphere is not on the image");
  // The spot's light direction: reflected view directions over a 7 x 7 window, each weighted by its value above
  // the window's floor times the solid angle of reflected directions the pixel spans, so that foreshortening near
  // the limb does not pull the mean (eq 5.3 at every pixel, not only at the brightest).
  double floor_value = 1e30;
  for (int dv = -3; dv <= 3; ++dv)
    for (int du = -3; du <= 3; ++du)
      floor_value = std::min<double>(floor_value, m.at(std::clamp(bu + du, 0, W - 1), std::clamp(bv + dv, 0, H - 1)));
  if (best / 9 < floor_value + 50) throw InputError("mirror image: no highlight on the sphere");
  auto reflect_at = [&](double x, double y, Eigen::Vector3d& r, Eigen::Vector3d& point) {
    const Eigen::Vector3d d = camera.ray(x, y);
    double t;
    if (!sphere.hit(d, t)) return false;
    point = t * d;
    const Eigen::Vector3d n = (point - sphere.centre).normalized(), wo = -d;
    r = 2 * n.dot(wo) * n - wo;  // eq 5.3
    return true;
  };
  Eigen::Vector3d sum_dir = Eigen::Vector3d::Zero(), sum_point = Eigen::Vector3d::Zero();
  double sum_w = 0;
  for (int dv = -3; dv <= 3; ++dv)
    for (int du = -3; du <= 3; ++du) {
      const int u = bu + du, v = bv + dv;
      if (u < 0 || v < 0 || u >= W || v >= H) continue;
      const double value = m.at(u, v) - floor_value;
      Eigen::Vector3d r, x, ra, rb, rc, rd, tmp;
      if (!(value > 0) || !reflect_at(u + 0.5, v + 0.5, r, x)) continue;
      double solid = 0;
      if (reflect_at(u + 0.25, v + 0.5, ra, tmp) && reflect_at(u + 0.75, v + 0.5, rb, tmp) &&
          reflect_at(u + 0.5, v + 0.25, rc, tmp) && reflect_at(u + 0.5, v + 0.75, rd, tmp))
        solid = 4 * (rb - ra).cross(rd - rc).norm();
      const double w = value * solid;
      sum_dir += w * r;
      sum_point += w * x;
      sum_w += w;
    }
  if (!(sum_w > 0)) throw InputError("mirror image: the highlight is off the sphere");
  const Eigen::Vector3d wi = sum_dir.normalized(), x = sum_point / sum_w;
  if (confidence) *confidence = std::max(0.0, (sphere.centre - x).normalized().dot(x.normalized()));
  if (!(light_distance > 0)) return wi;
  // The point along the reflected ray at light_distance from the sphere's centre.
  const Eigen::Vector3d q = x - sphere.centre;
  const double b = q.dot(wi), c = q.squaredNorm() - light_distance * light_distance;
  const double s = -b + std::sqrt(std::max(0.0, b * b - c));
  return (x + s * wi - sphere.centre).normalized();
}

std::vector<Eigen::Vector3d> fit_light_arc(std::span<const Eigen::Vector3d> measured, std::span<const double> weights,
                                           std::span<const double> angles_deg) {
  if (measured.size() != weights.size() || measured.size() != angles_deg.size())
    throw UsageError("fit_light_arc: one weight and one angle per measured direction");
  Eigen::Matrix3d b = Eigen::Matrix3d::Zero();
  int used = 0;
  auto e = [&](std::size_t l) {
    const double a = angles_deg[l] * pi / 180;
    return Eigen::Vector3d(std::cos(a), std::sin(a), 0);
  };
  for (std::size_t l = 0; l < measured.size(); ++l)
    if (weights[l] > 0) b += weights[l] * measured[l] * e(l).transpose(), ++used;
  if (used < 2) throw UsageError("fit_light_arc: at least 2 lights need a measured direction");
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(b, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d r = svd.matrixU() * d * svd.matrixV().transpose();
  std::vector<Eigen::Vector3d> out;
  for (std::size_t l = 0; l < measured.size(); ++l) out.push_back(r * e(l));
  return out;
}

GreyImage spatial_response(std::span<const GreyImage> flats) {
  if (flats.empty()) throw UsageError("spatial_response: give at least one flat field");
  const int W = flats[0].width, H = flats[0].height;
  GreyImage s{W, H, std::vector<float>(std::size_t(W) * std::size_t(H), 0.0f)};
  const double half = std::sqrt(0.05) / 2;
  for (const GreyImage& f : flats) {
    if (f.width != W || f.height != H) throw UsageError("spatial_response: flat fields of different sizes");
    double sum = 0;
    std::size_t n = 0;
    for (int v = int((0.5 - half) * H); v < int((0.5 + half) * H); ++v)
      for (int u = int((0.5 - half) * W); u < int((0.5 + half) * W); ++u) sum += f.at(u, v), ++n;
    if (!(sum > 0)) throw InputError("flat field: the centre of the image is dark");
    const double centre = sum / double(n);
    for (std::size_t p = 0; p < s.value.size(); ++p) s.value[p] += float(f.value[p] / centre / double(flats.size()));
  }
  // Vignetting is smooth: a least-squares 2-D polynomial of degree 4 in normalised coordinates keeps it and drops
  // the per-pixel noise of the flat fields.
  auto terms = [&](int u, int v, Eigen::Ref<Eigen::VectorXd> t) {
    const double x = (u + 0.5) / W * 2 - 1, y = (v + 0.5) / H * 2 - 1;
    Eigen::Index k = 0;
    for (int d = 0; d <= 4; ++d)
      for (int i = 0; i <= d; ++i) t[k++] = std::pow(x, i) * std::pow(y, d - i);
  };
  const Eigen::Index nt = 15;
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(nt, nt);
  Eigen::VectorXd atb = Eigen::VectorXd::Zero(nt), t(nt);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      terms(u, v, t);
      ata.selfadjointView<Eigen::Lower>().rankUpdate(t);
      atb += double(s.at(u, v)) * t;
    }
  const Eigen::VectorXd coef = ata.selfadjointView<Eigen::Lower>().ldlt().solve(atb);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      terms(u, v, t);
      s.value[std::size_t(v) * std::size_t(W) + std::size_t(u)] = float(std::max(1e-3, t.dot(coef)));
    }
  return s;
}

}  // namespace specula::acquire
