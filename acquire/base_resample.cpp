#include "specula/acquire/base_resample.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "specula/acquire/prior_resample.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

// src's samples minus the base at their configurations.
class ResidualSamples final : public brdf::SampleSource {
 public:
  ResidualSamples(const brdf::SampleSource& src, const BaseAtSamples& base) : src_(src), base_(base) {}
  std::size_t size() const override { return src_.size(); }
  std::size_t bands() const override { return src_.bands(); }
  std::size_t block_rows() const override { return src_.block_rows(); }
  void read_angles(std::size_t first, std::size_t count, std::span<double> out) const override {
    src_.read_angles(first, count, out);
  }
  void read_values(std::size_t first, std::size_t count, std::span<float> out) const override {
    src_.read_values(first, count, out);
    std::vector<double> angles(count * 4);
    std::vector<float> base(out.size());
    src_.read_angles(first, count, angles);
    base_(angles, base);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = std::isnan(base[i]) ? 0.0f : out[i] - base[i];
  }

 private:
  const brdf::SampleSource& src_;
  const BaseAtSamples& base_;
};

}  // namespace

double support_confidence(double gap, double max_gap, double reach) {
  const double r = gap / (reach * max_gap);
  return std::clamp(1 - r * r, 0.0, 1.0);
}

brdf::GridStats resample_on_base(const brdf::SampleSource& src, const brdf::ResampleOptions& o, double reach,
                                 const BaseAtSamples& base, std::span<float> grid, std::span<float> confidence) {
  const std::size_t b = src.bands();
  if (grid.size() != b * brdf::kMerlCells || confidence.size() != brdf::kMerlCells)
    throw UsageError("resampling on a base: grid or confidence of the wrong size");
  if (!(reach > 0 && reach <= 1))
    throw UsageError("resampling on a base: the confidence's reach (a fraction of max_gap) must be in (0, 1]");
  const ResidualSamples residuals(src, base);
  const brdf::SampleTree tree(src, o.mapping);
  Buffer<float> local(b * brdf::kMerlCells, -1.0f);
  std::vector<float> gaps(brdf::kMerlCells, -1.0f);
  const brdf::GridStats st = brdf::resample_grid(tree, residuals, o, local, gaps);
  const auto& cells = valid_cells();
  std::fill(confidence.begin(), confidence.end(), -1.0f);
  parallel_for(
      cells.size(),
      [&](std::size_t i) {
        const std::size_t cell = cells[i];
        const double c = support_confidence(gaps[cell], o.max_gap, reach);  // > 0 only where the kd-tree had support
        confidence[cell] = float(c);
        for (std::size_t k = 0; k < b && c > 0; ++k) {
          const std::size_t at = k * brdf::kMerlCells + cell;
          grid[at] = std::max(0.0f, float(grid[at] + c * local[at]));
        }
      },
      4096);
  return st;
}

BaseAtSamples base_from_grid(std::span<const float> grid, std::size_t bands) {
  return [grid, bands](std::span<const double> angles, std::span<float> values) {
    for (std::size_t s = 0; s < angles.size() / 4; ++s) {
      const brdf::StdAngles a{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]};
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
      for (std::size_t k = 0; k < bands; ++k) {
        const float v = grid[k * brdf::kMerlCells + cell];
        values[s * bands + k] = v >= 0 ? v : std::numeric_limits<float>::quiet_NaN();
      }
    }
  };
}

ModelResampleStats resample_with_model(const brdf::SampleSource& src, const WavelengthGrid& bands,
                                       const ModelResampleOptions& o, std::span<float> grid,
                                       std::span<float> confidence, std::unique_ptr<MicrofacetBrdf>* model) {
  if (bands.size() != src.bands())
    throw UsageError("model resampling: " + std::to_string(bands.size()) + " wavelengths for samples of " +
                     std::to_string(src.bands()) + " bands");
  ModelResampleStats st;
  const auto t0 = std::chrono::steady_clock::now();
  const PriorObservations obs = cell_means(src);
  auto fitted = std::make_unique<MicrofacetBrdf>(fit_model(obs, bands, o.fit, &st.fit));
  const std::size_t b = bands.size();
  std::fill(grid.begin(), grid.end(), -1.0f);
  const auto& cells = valid_cells();
  parallel_for(
      cells.size(), [b] { return std::vector<double>(b); },
      [&](std::size_t i, std::vector<double>& f) {
        fitted->eval(brdf::std_angles(brdf::merl_cell_centre(brdf::merl_cell(cells[i]))), f);
        for (std::size_t k = 0; k < b; ++k) grid[k * brdf::kMerlCells + cells[i]] = float(f[k]);
      },
      4096);
  st.fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const BaseAtSamples base = [&](std::span<const double> angles, std::span<float> values) {
    parallel_for(
        angles.size() / 4, [b] { return std::vector<double>(b); },
        [&](std::size_t s, std::vector<double>& f) {
          fitted->eval(brdf::StdAngles{angles[4 * s], angles[4 * s + 1], angles[4 * s + 2], angles[4 * s + 3]}, f);
          for (std::size_t k = 0; k < b; ++k) values[s * b + k] = float(f[k]);
        },
        4096);
  };
  st.local = resample_on_base(src, o.local, o.confidence_reach, base, grid, confidence);
  st.filled_cells = valid_cells().size();
  if (model) *model = std::move(fitted);
  return st;
}

}  // namespace specula::acquire
