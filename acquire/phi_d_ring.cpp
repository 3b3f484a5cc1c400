#include "specula/acquire/phi_d_ring.h"

#include <cmath>

namespace specula::acquire {

int settle_phi_d_ring(std::span<float> ring, double keep) {
  double sum = 0;
  int n = 0;
  for (const float v : ring)
    if (v > 0) sum += std::log(double(v)), ++n;
  if (n == 0) return 0;
  const double mean = sum / n;
  for (float& v : ring)
    if (v > 0) v = float(std::exp(mean + keep * (std::log(double(v)) - mean)));
  return n;
}

double sin2_share(double a, double b) { return std::pow(std::sin(a), 2) / std::pow(std::sin(b), 2); }

}  // namespace specula::acquire
