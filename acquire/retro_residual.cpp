#include "specula/acquire/retro_residual.h"

#include <algorithm>
#include <chrono>
#include <nlohmann/json.hpp>
#include <vector>

#include "specula/acquire/scan_holdout.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"

namespace specula::acquire {
namespace {

// The mean of blend_error over band's cells, in their order, of grid, or of below at theta_d rows under `rows`.
double band_error(const PriorObservations& band, std::span<const float> grid, std::span<const float> below, int rows,
                  std::size_t b, double eps) {
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  double sum = 0;
  for (std::size_t o = 0; o < band.cell.size(); ++o) {
    const std::size_t v = band.cell[o];
    const std::span<const float> g = brdf::merl_cell(cells[v]).theta_d < rows ? below : grid;
    sum += blend_error(band, o, cells[v], cosines[v], 1.0, g, g, b, eps);
  }
  return sum / double(band.cell.size());
}

}  // namespace

RetroResidualChoice choose_retro_residuals(const brdf::SampleSource& kept, const PriorObservations& band,
                                           std::span<const float> rehearsal, const LogResidualOptions& o, double eps) {
  const std::size_t b = kept.bands();
  if (b == 0 || rehearsal.size() != b * brdf::kMerlCells || band.values.size() != band.cell.size() * b)
    throw UsageError("retro residuals: the rehearsal grid and the held band must be of the samples' bands");
  if (band.cell.empty()) throw InputError("retro residuals: no held band cell to judge the carry at");
  const auto t0 = std::chrono::steady_clock::now();
  RetroResidualChoice c;
  LogResidualOptions with = o, without = o;
  with.into_retro_band = true;
  without.into_retro_band = false;
  with.measure_after = without.measure_after = false;
  Buffer<float> carried(rehearsal.begin(), rehearsal.end());
  c.carried_rows = correct_by_log_residuals(kept, with, eps, carried).carried_rows;
  c.cells = band.cell.size();
  c.error_carried = band_error(band, carried, carried, 0, b, eps);
  if (o.passes == 1) {  // one pass takes its residuals against the grid as given: the carry changes its rows only
    c.error_plain = band_error(band, carried, rehearsal, c.carried_rows, b, eps);
  } else {
    Buffer<float> plain(rehearsal.begin(), rehearsal.end());
    correct_by_log_residuals(kept, without, eps, plain);
    c.error_plain = band_error(band, plain, plain, 0, b, eps);
  }
  c.carried = c.error_carried < c.error_plain;
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return c;
}

int carry_rehearsal_rows(int band_end, int lowest, const LogResidualOptions& o) {
  return std::max(band_end - 1, lowest - o.radius) + o.passes * (o.radius + 1) + 1;
}

nlohmann::ordered_json retro_residual_json(const RetroResidualChoice& c) {
  return {{"carried", c.carried}, {"error_carried", c.error_carried}, {"error_plain", c.error_plain},
          {"cells", c.cells},     {"carried_rows", c.carried_rows},   {"seconds", c.seconds}};
}

}  // namespace specula::acquire
