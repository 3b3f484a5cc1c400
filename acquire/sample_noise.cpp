#include "specula/acquire/sample_noise.h"

#include <string>

#include "specula/core/error.h"

namespace specula::acquire {

SampleNoise::SampleNoise(const Capture& cap, const std::filesystem::path& dir, int light, const SpectralCalibration& s,
                         const SensorNoise& noise, const HdrOptions& o)
    : recovery2_(s.recovery.cwiseAbs2()) {
  std::vector<std::vector<double>> times(cap.channels());
  for (const auto& im : cap.images)
    if (im.kind == ImageKind::scene && im.light == light && im.band >= 0 && std::size_t(im.band) < times.size())
      times[std::size_t(im.band)].push_back(im.exposure_s);
  for (std::size_t k = 0; k < times.size(); ++k) {
    if (times[k].empty())
      throw InputError((dir / "manifest.json").string() + ": light " + std::to_string(light) +
                       " has no scene exposure in channel " + std::to_string(k));
    channels_.emplace_back(times[k], cap.bit_depth, noise, o);
  }
}

Eigen::VectorXd SampleNoise::variance(const std::vector<HdrImage>& hdr, std::size_t p, double scale) const {
  Eigen::VectorXd rate_variance(Eigen::Index(channels_.size()));
  for (std::size_t k = 0; k < channels_.size(); ++k) rate_variance[Eigen::Index(k)] = channels_[k](hdr[k].rate[p]);
  return recovery2_ * rate_variance / (scale * scale);
}

}  // namespace specula::acquire
