#include "specula/acquire/simulate.h"

#include <algorithm>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {

namespace {

class GridMaterial final : public brdf::SpectralModel {
 public:
  GridMaterial(std::shared_ptr<const store::Grid> grid, WavelengthGrid target, GridLookup lookup)
      : SpectralModel(std::move(target)), grid_(std::move(grid)), lookup_(lookup) {
    const WavelengthGrid& from = grid_->wavelengths;
    for (std::size_t k = 0; k < bands(); ++k) {
      const double l = wavelengths()[k];
      std::size_t a = 0, b = 0;
      double t = 0;
      if (l <= from.front()) {
        a = b = 0;
      } else if (l >= from.back()) {
        a = b = from.size() - 1;
      } else {
        b = std::size_t(std::upper_bound(from.values().begin(), from.values().end(), l) - from.values().begin());
        a = b - 1;
        t = (l - from[a]) / (from[b] - from[a]);
      }
      lo_.push_back(a), hi_.push_back(b), t_.push_back(t);
    }
  }
  using SpectralModel::eval;
  void eval(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo, std::span<double> out) const override {
    std::fill(out.begin(), out.end(), 0.0);
    if (wi.z() <= 0 || wo.z() <= 0) return;
    if (lookup_ == GridLookup::nearest) {
      const brdf::StdAngles a{std::acos(std::min(1.0, wi.z())), std::atan2(wi.y(), wi.x()),
                              std::acos(std::min(1.0, wo.z())), std::atan2(wo.y(), wo.x())};
      const std::size_t cell = brdf::merl_index(brdf::merl_cell(a));
      for (std::size_t k = 0; k < out.size(); ++k) out[k] = value(k, cell, true);
      return;
    }
    trilinear(brdf::half_diff(wi, wo), out);
  }

 private:
  // Band k (of the target) at a cell: the grid's bands interpolated; negative (no data) counts as 0 when `clamp`.
  double value(std::size_t k, std::size_t cell, bool clamp) const {
    float va = grid_->brdf[lo_[k] * brdf::kMerlCells + cell], vb = grid_->brdf[hi_[k] * brdf::kMerlCells + cell];
    if (clamp) va = std::max(0.0f, va), vb = std::max(0.0f, vb);
    if (va < 0 || vb < 0) return -1;
    return grid_->scale * ((1 - t_[k]) * va + t_[k] * vb);
  }

  // Trilinear in MERL index space between the 8 surrounding cell centres; corners without data are left out and
  // the weights of the others renormalised (0 when none has data).
  void trilinear(const brdf::HalfDiff& h, std::span<double> out) const {
    const brdf::MerlCorners corners = brdf::merl_trilinear(h);
    std::vector<double> weight(out.size(), 0.0);
    for (std::size_t c = 0; c < 8; ++c) {
      const double w = corners.weight[c];
      if (w <= 0) continue;
      for (std::size_t k = 0; k < out.size(); ++k) {
        const double v = value(k, corners.cell[c], false);
        if (v < 0) continue;
        out[k] += w * v;
        weight[k] += w;
      }
    }
    for (std::size_t k = 0; k < out.size(); ++k) out[k] = weight[k] > 0 ? out[k] / weight[k] : 0.0;
  }

  std::shared_ptr<const store::Grid> grid_;
  GridLookup lookup_;
  std::vector<std::size_t> lo_, hi_;
  std::vector<double> t_;
};

}  // namespace

std::unique_ptr<brdf::SpectralModel> grid_material(std::shared_ptr<const store::Grid> grid,
                                                   const WavelengthGrid& target, GridLookup lookup) {
  if (!grid || grid->brdf.size() != grid->bands() * brdf::kMerlCells || grid->bands() == 0)
    throw UsageError("grid_material: a grid of bands x 90 x 90 x 180 values");
  return std::make_unique<GridMaterial>(std::move(grid), target, lookup);
}

}  // namespace specula::acquire
