#include "specula/acquire/truth.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace specula::acquire {

void for_each_sample(const store::Store& s, const std::string& name,
                     const std::function<void(const double* angles, const float* values)>& fn) {
  const store::SamplesInfo info = s.samples_info(name);
  const std::size_t block = 1 << 16;
  std::vector<double> angles;
  std::vector<float> values;
  for (std::size_t first = 0; first < info.size; first += block) {
    const std::size_t n = std::min(block, info.size - first);
    angles.resize(4 * n);
    values.resize(n * info.bands);
    s.read_samples(name, first, n, angles, values);
    for (std::size_t i = 0; i < n; ++i) fn(&angles[4 * i], &values[i * info.bands]);
  }
}

std::pair<double, double> light_direction_error(const Capture& cap, const Calibration& c) {
  if (!cap.truth || c.light_dirs.empty() || cap.truth->light_dirs.size() != c.light_dirs.size()) return {-1, -1};
  double sum = 0, worst = 0;
  for (std::size_t l = 0; l < c.light_dirs.size(); ++l) {
    const auto& t = cap.truth->light_dirs[l];
    const double a =
        std::acos(std::clamp(c.light_dirs[l].dot(Eigen::Vector3d(t[0], t[1], t[2]).normalized()), -1.0, 1.0)) * 180 /
        std::numbers::pi;
    sum += a;
    worst = std::max(worst, a);
  }
  return {sum / double(c.light_dirs.size()), worst};
}

std::pair<double, double> sample_error(const store::Store& s, const std::string& name,
                                       const brdf::SpectralModel& model) {
  const store::SamplesInfo info = s.samples_info(name);
  const std::size_t stride = std::max<std::size_t>(1, info.size / 1000000);
  std::vector<double> err, ratio, f(info.bands);
  std::size_t index = 0;
  for_each_sample(s, name, [&](const double* angles, const float* values) {
    if (index++ % stride != 0) return;
    model.eval(brdf::StdAngles{angles[0], angles[1], angles[2], angles[3]}, f);
    for (std::size_t b = 0; b < info.bands; ++b)
      if (f[b] > 1e-3) {
        ratio.push_back(values[b] / f[b]);
        err.push_back(std::abs(ratio.back() - 1));
      }
  });
  if (err.empty()) return {-1, -1};
  auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  return {median(err), median(ratio)};
}

}  // namespace specula::acquire
