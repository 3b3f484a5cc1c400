#include "specula/acquire/log_residual.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include "specula/acquire/prior.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/buffer.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::acquire {
namespace {

constexpr std::size_t kCells = brdf::kMerlCells;

// A sample's residual per band against the grid looked up where it lies, and the cell it falls in; false when it
// is left out (below the horizon, a value < 0 or not finite, a band without data around it).
bool sample_residual(const double* angles, const float* values, std::span<const float> grid, std::size_t bands,
                     double eps, float* residual, std::size_t& cell) {
  const brdf::StdAngles a{angles[0], angles[1], angles[2], angles[3]};
  if (!(std::isfinite(a.theta_i) && std::isfinite(a.theta_o) && a.theta_i >= 0 && a.theta_o >= 0 &&
        a.theta_i < std::numbers::pi / 2 && a.theta_o < std::numbers::pi / 2))
    return false;
  const brdf::HalfDiff h = brdf::half_diff(a);
  const brdf::MerlCorners corners = brdf::merl_trilinear(h);
  const double cc = std::cos(a.theta_i) * std::cos(a.theta_o);
  for (std::size_t k = 0; k < bands; ++k) {
    const double s = values[k];
    if (!std::isfinite(s) || s < 0) return false;
    double sum = 0, weight = 0;
    for (std::size_t c = 0; c < 8; ++c) {
      const float v = grid[k * kCells + corners.cell[c]];
      if (corners.weight[c] <= 0 || v < 0) continue;
      sum += corners.weight[c] * v;
      weight += corners.weight[c];
    }
    if (weight <= 0) return false;
    residual[k] = float(std::log((s * cc + eps) / (sum / weight * cc + eps)));
  }
  cell = brdf::merl_index(brdf::merl_cell(h));
  return true;
}

// Each plane of `planes` x kCells replaced by its box sums of half-width radius along one index axis (n cells apart
// by stride; zero beyond the ends, or wrapped), line by line.
void box_sums(std::span<float> a, std::size_t planes, std::size_t n, std::size_t stride, bool wrap, int radius) {
  const std::size_t lines = planes * kCells / n;
  parallel_for(
      lines, [] { return std::vector<float>(); },
      [&](std::size_t line, std::vector<float>& tmp) {
        const std::size_t plane = line / (kCells / n), rest = line % (kCells / n);
        const std::size_t first = plane * kCells + rest / stride * stride * n + rest % stride;
        tmp.resize(n);
        for (std::size_t i = 0; i < n; ++i) tmp[i] = a[first + i * stride];
        for (std::size_t i = 0; i < n; ++i) {
          float sum = 0;
          for (int d = -radius; d <= radius; ++d) {
            const long j = long(i) + d;
            if (wrap)
              sum += tmp[std::size_t((j % long(n) + long(n)) % long(n))];
            else if (j >= 0 && j < long(n))
              sum += tmp[std::size_t(j)];
          }
          a[first + i * stride] = sum;
        }
      },
      64);
}

// The RMS of every usable sample's residuals, counted into samples, the lowest theta_d row of their cells into
// lowest; with sums (not empty), each sample's residuals (planes 0 .. bands-1) and a count (plane bands) added at its
// cell, in sample order.
double add_residuals(const brdf::SampleSource& src, std::span<const float> grid, double eps, std::span<float> sums,
                     std::size_t& samples, int& lowest) {
  const std::size_t b = src.bands(), n = src.size(), block = src.block_rows();
  std::vector<double> angles;
  std::vector<float> values, residual;
  std::vector<std::int64_t> cell_of;
  double squares = 0;
  samples = 0;
  lowest = brdf::kMerlThetaD;
  Progress progress("log residuals", n);
  for (std::size_t first = 0; first < n; first += block) {
    check_interrupt();
    const std::size_t count = std::min(block, n - first);
    angles.resize(count * 4);
    values.resize(count * b);
    residual.resize(count * b);
    cell_of.resize(count);
    src.read_angles(first, count, angles);
    src.read_values(first, count, values);
    parallel_for(
        count,
        [&](std::size_t s) {
          std::size_t cell = 0;
          const bool ok = sample_residual(&angles[4 * s], &values[s * b], grid, b, eps, &residual[s * b], cell);
          cell_of[s] = ok ? std::int64_t(cell) : -1;
        },
        4096);
    for (std::size_t s = 0; s < count; ++s) {  // in sample order: the sums do not depend on the thread count
      if (cell_of[s] < 0) continue;
      const std::size_t cell = std::size_t(cell_of[s]);
      for (std::size_t k = 0; k < b; ++k) {
        if (!sums.empty()) sums[k * kCells + cell] += residual[s * b + k];
        squares += double(residual[s * b + k]) * residual[s * b + k];
      }
      if (!sums.empty()) sums[b * kCells + cell] += 1;
      lowest = std::min(lowest, brdf::merl_cell(cell).theta_d);
      ++samples;
    }
    progress.advance(count);
  }
  return samples ? std::sqrt(squares / double(samples * b)) : 0.0;
}

// In theta_h rows [from[d], rows) of theta_d row d of every plane, each phi_d ring's values replaced by their total.
void ring_totals(std::span<float> a, std::size_t planes, int rows, const std::array<int, brdf::kMerlThetaD>& from) {
  constexpr std::size_t ring = brdf::kMerlPhiD, row = std::size_t(brdf::kMerlThetaD) * ring;
  parallel_for(
      planes * std::size_t(rows) * brdf::kMerlThetaD,
      [&](std::size_t task) {
        const std::size_t plane = task / (std::size_t(rows) * brdf::kMerlThetaD),
                          rest = task % (std::size_t(rows) * brdf::kMerlThetaD);
        if (int(rest / brdf::kMerlThetaD) < from[rest % brdf::kMerlThetaD]) return;
        float* first = &a[plane * kCells + rest / brdf::kMerlThetaD * row + rest % brdf::kMerlThetaD * ring];
        std::fill_n(first, ring, float(std::accumulate(first, first + ring, 0.0)));
      },
      256);
}

// Every plane's values at theta_d row `from` copied into the rows below it, column by column.
void carry_down(std::span<float> a, std::size_t planes, int from) {
  constexpr std::size_t row = brdf::kMerlPhiD, column = std::size_t(brdf::kMerlThetaD) * row;
  parallel_for(
      planes * brdf::kMerlThetaH,
      [&](std::size_t ph) {
        float* first = &a[ph * column];
        for (int d = 0; d < from; ++d) std::copy_n(first + std::size_t(from) * row, row, first + std::size_t(d) * row);
      },
      8);
}

// One pass: the box means of the residuals (carried into the retro band when asked) multiplied into every valid
// cell with data they reach; the cells corrected.
std::size_t correct_once(const brdf::SampleSource& src, const LogResidualOptions& o, double eps, std::span<float> grid,
                         std::span<float> sums, double& rms, LogResidualStats& st) {
  const std::size_t b = src.bands();
  std::fill(sums.begin(), sums.end(), 0.0f);
  int lowest = 0;
  rms = add_residuals(src, grid, eps, sums, st.samples, lowest);
  box_sums(sums, b + 1, brdf::kMerlPhiD, 1, true, o.radius);
  box_sums(sums, b + 1, brdf::kMerlThetaD, brdf::kMerlPhiD, false, o.radius);
  box_sums(sums, b + 1, brdf::kMerlThetaH, std::size_t(brdf::kMerlPhiD) * brdf::kMerlThetaD, false, o.radius);
  if (o.ring_rows > 0) ring_totals(sums, b + 1, o.ring_rows, o.ring_from);
  st.carried_rows = o.into_retro_band && lowest < brdf::kMerlThetaD ? std::max(0, lowest - o.radius) : 0;
  if (st.carried_rows > 0) carry_down(sums, b + 1, st.carried_rows);
  const auto& cells = valid_cells();
  const auto& cosines = valid_cell_cosines();
  std::vector<std::uint8_t> corrected(cells.size(), 0);
  parallel_for(
      cells.size(),
      [&](std::size_t i) {
        const std::size_t cell = cells[i];
        const float count = sums[b * kCells + cell];
        if (count <= 0 || grid[cell] < 0) return;
        const double cc = cosines[i];
        for (std::size_t k = 0; k < b; ++k) {
          float& v = grid[k * kCells + cell];
          if (v < 0) continue;
          const double m = double(sums[k * kCells + cell]) / count;
          v = float(std::max(0.0, (std::exp(m) * (v * cc + eps) - eps) / cc));
        }
        corrected[i] = 1;
      },
      4096);
  return std::size_t(std::count(corrected.begin(), corrected.end(), std::uint8_t(1)));
}

}  // namespace

LogResidualStats correct_by_log_residuals(const brdf::SampleSource& src, const LogResidualOptions& o, double eps,
                                          std::span<float> grid) {
  const std::size_t b = src.bands();
  if (b == 0 || grid.size() != b * kCells)
    throw UsageError("log residuals: the grid must hold bands x 1458000 values for the samples' bands");
  if (o.radius < 0 || o.radius > 10) throw UsageError("log residuals: radius must lie in [0, 10] cells");
  if (o.passes < 1 || o.passes > 10) throw UsageError("log residuals: passes must lie in [1, 10]");
  if (o.ring_rows < 0 || o.ring_rows >= brdf::kMerlThetaH)
    throw UsageError("log residuals: ring_rows " + std::to_string(o.ring_rows) + " must lie in [0, 90)");
  if (!(eps > 0) || !std::isfinite(eps)) throw UsageError("log residuals: epsilon must be positive");
  const auto t0 = std::chrono::steady_clock::now();
  LogResidualStats st;
  Buffer<float> sums;  // zeroed by each pass
  sums.resize((b + 1) * kCells);
  for (int pass = 0; pass < o.passes; ++pass) {
    double rms = 0;
    st.corrected_cells = correct_once(src, o, eps, grid, sums, rms, st);
    if (pass == 0) st.rms_before = rms;
  }
  Buffer<float>().swap(sums);
  if (o.measure_after) {
    int lowest = 0;
    st.rms_after = add_residuals(src, grid, eps, {}, st.samples, lowest);
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

nlohmann::ordered_json log_residuals_json(const LogResidualStats& st, const LogResidualOptions& o) {
  return {{"radius", o.radius},          {"passes", o.passes},
          {"ring_rows", o.ring_rows},    {"carried_rows", st.carried_rows},
          {"samples", st.samples},       {"corrected_cells", st.corrected_cells},
          {"rms_before", st.rms_before}, {"rms_after", st.rms_after},
          {"seconds", st.seconds}};
}

}  // namespace specula::acquire
