#include "specula/acquire/retro_trend.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::acquire {
namespace {

constexpr std::array<double, 11> kCandidates = {1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0};
constexpr std::size_t kP = kCandidates.size();
constexpr int kRows = 2 * kRetroLearnedRows;  // theta_d rows a column's widest band and its known rows span
constexpr int kFirstThetaH = 10;

// One theta_h row's squared errors (kRetroLearnedRows x kP) and band cells (kRetroLearnedRows).
struct RowTally {
  std::array<double, kRetroLearnedRows * kP> error{};
  std::array<double, kRetroLearnedRows> count{};
};

// The errors of every width and candidate for one column's channel: y its ln values at rows [0, 2 widest).
void tally_column(std::span<const double> y, int widest, const std::array<std::array<double, kRows>, kP>& x,
                  RowTally& t) {
  for (int b = 1; b <= widest; ++b) {
    t.count[std::size_t(b - 1)] += b;
    for (std::size_t c = 0; c < kP; ++c) {
      const TrendLine l = shrunk_line(std::span(x[c]).subspan(std::size_t(b), std::size_t(b)),
                                      y.subspan(std::size_t(b), std::size_t(b)));
      double e = 0;
      for (int r = 0; r < b; ++r) e += std::pow(l.at(x[c][std::size_t(r)]) - y[std::size_t(r)], 2);
      t.error[std::size_t(b - 1) * kP + c] += e;
    }
  }
}

}  // namespace

TrendLine shrunk_line(std::span<const double> x, std::span<const double> y) {
  if (x.size() != y.size()) throw UsageError("retro trend: a line needs as many abscissae as values");
  const double n = double(y.size());
  TrendLine l;
  for (std::size_t i = 0; i < y.size(); ++i) {
    l.x_mean += x[i] / n;
    l.mean += y[i] / n;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    sxy += (x[i] - l.x_mean) * y[i];
    sxx += (x[i] - l.x_mean) * (x[i] - l.x_mean);
  }
  l.slope = sxx > 0 ? sxy / sxx : 0.0;
  if (y.size() > 2 && l.slope != 0) {
    double rss = 0;
    for (std::size_t i = 0; i < y.size(); ++i) rss += std::pow(y[i] - l.at(x[i]), 2);
    l.slope *= std::max(0.0, 1.0 - rss / ((n - 2) * sxx) / (l.slope * l.slope));
  }
  return l;
}

double retro_abscissa(int r, double exponent) { return std::pow(retro_row_centre(r), exponent); }

double retro_exponent(std::span<const double> exponents, int rows) {
  if (exponents.empty()) return 2.0;
  return exponents[std::size_t(std::clamp(rows, 1, int(exponents.size())) - 1)];
}

std::span<const double> retro_exponent_candidates() { return kCandidates; }

RetroExponentTally::RetroExponentTally() : error_(kRetroLearnedRows * kP, 0.0), count_(kRetroLearnedRows, 0.0) {}

void RetroExponentTally::add(std::span<const float> values, std::size_t channels, std::size_t h0, std::size_t rows) {
  constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;
  if (channels == 0 || values.size() != channels * rows * kRow || h0 + rows > std::size_t(brdf::kMerlThetaH))
    throw UsageError("retro trend: rows of channels x theta_h rows x MERL theta_d x phi_d values needed");
  std::array<std::array<double, kRows>, kP> x;
  for (std::size_t c = 0; c < kP; ++c)
    for (int r = 0; r < kRows; ++r) x[c][std::size_t(r)] = retro_abscissa(r, kCandidates[c]);
  std::vector<RowTally> part(rows);
  parallel_for(rows, [&](std::size_t i) {
    const int h = int(h0 + i);
    if (h < kFirstThetaH) return;
    std::vector<double> y(channels * kRows);
    for (int p = 0; p < brdf::kMerlPhiD; ++p) {
      int known = 0;  // rows [0, known) valid with values > 0 in every channel
      for (bool ok = true; ok && known < kRows; known += ok) {
        ok = brdf::merl_cell_valid({.theta_h = h, .theta_d = known, .phi_d = p});
        for (std::size_t k = 0; ok && k < channels; ++k) {
          const float v = values[(k * rows + i) * kRow + std::size_t(known) * brdf::kMerlPhiD + std::size_t(p)];
          ok = v > 0 && std::isfinite(v);
          if (ok) y[k * kRows + std::size_t(known)] = std::log(double(v));
        }
      }
      for (std::size_t k = 0; k < channels && known >= 2; ++k)
        tally_column(std::span(y).subspan(k * kRows, kRows), known / 2, x, part[i]);
    }
  });
  for (const RowTally& t : part) {
    for (std::size_t j = 0; j < error_.size(); ++j) error_[j] += t.error[j];
    for (std::size_t j = 0; j < count_.size(); ++j) count_[j] += t.count[j];
  }
}

std::vector<double> RetroExponentTally::exponents() const {
  std::vector<double> out(kRetroLearnedRows, 2.0);
  for (std::size_t b = 0; b < out.size(); ++b) {
    if (count_[b] == 0) continue;
    std::size_t best = kP - 1;
    for (std::size_t c = kP - 1; c-- > 0;)
      if (error_[b * kP + c] < error_[b * kP + best]) best = c;
    out[b] = kCandidates[best];
  }
  return out;
}

double RetroExponentTally::mean_error(int width, std::size_t candidate) const {
  if (width < 1 || width > kRetroLearnedRows || candidate >= kP)
    throw UsageError("retro trend: no such band width or candidate exponent");
  const std::size_t b = std::size_t(width - 1);
  return count_[b] > 0 ? error_[b * kP + candidate] / count_[b] : 0.0;
}

}  // namespace specula::acquire
