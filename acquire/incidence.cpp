#include "specula/acquire/incidence.h"

#include <algorithm>

#include "specula/core/brdf_mapping.h"
#include "specula/core/error.h"

namespace specula::acquire {

std::vector<PlanePoints> incidence_plane_points(const store::Store& s, const std::string& name,
                                                std::span<const double> theta_i, double eps, std::size_t band,
                                                std::size_t limit) {
  const store::SamplesInfo info = s.samples_info(name);
  if (band >= info.bands)
    throw UsageError("incidence_plane_points: band " + std::to_string(band) + " of samples " + name + ", which have " +
                     std::to_string(info.bands) + " bands");
  std::vector<PlanePoints> out(theta_i.size());
  auto done = [&] {
    return std::all_of(out.begin(), out.end(), [&](const PlanePoints& p) { return p.points.size() >= limit; });
  };
  const std::size_t block = std::max<std::size_t>(info.chunk_rows, 65536);
  std::vector<double> angles;
  std::vector<float> values;
  std::size_t scanned = 0;
  for (std::size_t first = 0; first < info.size && !done(); first += block) {
    const std::size_t n = std::min(block, info.size - first);
    angles.resize(4 * n);
    s.read_samples(name, first, n, angles, {});
    scanned += n;
    bool have_values = false;  // a block's values are read only when some of its samples lie in a plane
    for (std::size_t i = 0; i < n; ++i) {
      const brdf::IsoAngles a =
          brdf::iso_angles({angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]});
      for (std::size_t k = 0; k < theta_i.size(); ++k) {
        if (out[k].points.size() >= limit) continue;
        const auto x = brdf::incidence_plane_angle(a, theta_i[k], eps);
        if (!x) continue;
        if (!have_values) {
          values.resize(n * info.bands);
          s.read_samples(name, first, n, {}, values);
          have_values = true;
        }
        out[k].points.push_back({*x, values[i * info.bands + band]});
      }
    }
  }
  for (PlanePoints& p : out) p.scanned = scanned;
  return out;
}

}  // namespace specula::acquire
