#pragma once
// What the prior's choices from the scan itself share (acquire/prior_reach.h, acquire/cap_weight.h): a source of
// the samples a holdout keeps, each sample's cell, the log-domain error of a blend against held-out cell means, and
// that error's eps scaled to a dark material.
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_resample.h"

namespace specula::acquire {

/// The samples of a source whose label in `held` is 0, in their order (the source outlives it).
class KeptSamples final : public brdf::SampleSource {
 public:
  KeptSamples(const brdf::SampleSource& src, std::span<const std::uint8_t> held);
  std::size_t size() const override { return kept_.size(); }
  std::size_t bands() const override { return src_.bands(); }
  std::size_t block_rows() const override { return src_.block_rows(); }
  bool has_variance() const override { return src_.has_variance(); }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override;
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override;
  void read_variance(std::size_t first, std::size_t count, std::span<float> out) const override;

 private:
  template <class T, class Read>
  void gather(std::size_t first, std::size_t count, std::size_t width, std::span<T> out, const Read& read) const;

  const brdf::SampleSource& src_;
  std::vector<std::uint32_t> kept_;
};

/// Each sample's position in valid_cells() (or -1), its angles read in the source's blocks; with theta_d_rows (one
/// per sample) each sample's own theta_d row too, whether its cell lies above the horizon or not (kMerlThetaD for
/// angles not finite). UsageError on theta_d_rows' size; Interrupted between blocks.
std::vector<std::int32_t> sample_slots(const brdf::SampleSource& src, std::span<std::uint8_t> theta_d_rows = {});

/// The mean over bands of (ln((blend cc + eps) / (target cc + eps)))^2 at observation o of obs (MERL cell `cell`),
/// blend = mix_estimates(kd, fitted, c, cc, eps, log) (prior_resample.h), target the observation's values, cc the
/// cell's cos theta_i cos theta_o; grids bands x kMerlCells.
double blend_error(const PriorObservations& obs, std::size_t o, std::size_t cell, double cc, double c,
                   std::span<const float> fitted, std::span<const float> kd, std::size_t b, double eps,
                   bool log = false);

/// The error's eps: the prior's times min(1, the median over obs's cells of the band-mean cos-weighted value / the
/// median of the prior's reference at the same cells), floored at 1e-6 of it; the prior's when obs is empty.
double judge_epsilon(const PriorObservations& obs, const BrdfPrior& prior, std::size_t b);

/// Per observation o of obs and entry l < m (row-major, obs x m), blend_error at the kd-tree's weight weight(cell, l),
/// cell the observation's MERL cell (the fit alone where kd has no support); on all threads.
std::vector<double> blend_error_table(const PriorObservations& obs, std::span<const float> fitted,
                                      std::span<const float> kd, std::size_t b, std::size_t m, double eps, bool log,
                                      const std::function<double(std::size_t cell, std::size_t l)>& weight);

/// blend_error_table at the weights of ladder: per observation and w, the error of mix_estimates(kd, fitted, w, ...,
/// log) (fitted alone where kd has no support).
std::vector<double> weight_error_table(const PriorObservations& obs, std::span<const float> fitted,
                                       std::span<const float> kd, std::size_t b, std::span<const double> ladder,
                                       double eps, bool log);

/// Per weight w of ladder, the mean over the observations of obs of weight_error_table, summed in observation order;
/// zeros when obs is empty.
std::vector<double> weight_errors(const PriorObservations& obs, std::span<const float> fitted,
                                  std::span<const float> kd, std::size_t b, std::span<const double> ladder, double eps,
                                  bool log);

/// The index of the least entry (the first on a tie).
std::size_t least(const std::vector<double>& v);

}  // namespace specula::acquire
