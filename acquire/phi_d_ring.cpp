#include "specula/acquire/phi_d_ring.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "specula/core/brdf_geometry.h"

namespace specula::acquire {

std::size_t settle_phi_d_rings(std::span<float> grid, std::size_t bands, std::size_t first, double keep) {
  std::array<bool, brdf::kMerlPhiD> positive{};
  for (std::size_t k = 0; k < bands; ++k) {
    const std::span<float> ring = grid.subspan(k * brdf::kMerlCells + first, brdf::kMerlPhiD);
    double sum = 0;
    int n = 0;
    for (const float v : ring)
      if (v > 0) sum += std::log(double(v)), ++n;
    if (n == 0) continue;
    const double mean = sum / n;
    for (std::size_t p = 0; p < ring.size(); ++p)
      if (ring[p] > 0) {
        ring[p] = float(std::exp(mean + keep * (std::log(double(ring[p])) - mean)));
        positive[p] = true;
      }
  }
  return std::size_t(std::ranges::count(positive, true));
}

double sin2_share(double a, double b) { return std::pow(std::sin(a), 2) / std::pow(std::sin(b), 2); }

}  // namespace specula::acquire
