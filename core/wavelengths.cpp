#include "specula/core/wavelengths.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numeric>
#include <sstream>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula {
namespace {

double parse_number(std::string_view text, std::string_view spec) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  double v = 0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty())
    throw UsageError("wavelengths '" + std::string(spec) + "': '" + std::string(text) +
                     "' is not a number; use FIRST:LAST:STEP (e.g. 420:720:10) or a comma list");
  return v;
}

}  // namespace

WavelengthGrid::WavelengthGrid(std::vector<double> nm, std::string_view context) : nm_(std::move(nm)) {
  for (std::size_t i = 0; i < nm_.size(); ++i) {
    if (!std::isfinite(nm_[i]) || nm_[i] <= 0)
      throw InputError(std::string(context) + ": wavelength " + std::to_string(i) + " is " + num(nm_[i]) +
                       "; wavelengths must be finite and positive (nm)");
    if (i > 0 && !(nm_[i] > nm_[i - 1]))
      throw InputError(std::string(context) + ": wavelengths are not increasing (" + num(nm_[i - 1]) + " nm then " +
                       num(nm_[i]) + " nm at index " + std::to_string(i) + ")");
  }
}

std::vector<std::size_t> ascending_band_order(std::span<const double> nm, std::vector<std::size_t> bands,
                                              const std::function<void(std::size_t, std::size_t)>& repeated) {
  std::stable_sort(bands.begin(), bands.end(), [&](std::size_t a, std::size_t b) { return nm[a] < nm[b]; });
  for (std::size_t i = 1; i < bands.size(); ++i)
    if (nm[bands[i]] == nm[bands[i - 1]]) {
      repeated(std::min(bands[i], bands[i - 1]), std::max(bands[i], bands[i - 1]));
      throw LibraryError("ascending_band_order: wavelength " + num(nm[bands[i]]) +
                         " appears twice and the caller's handler did not throw");
    }
  return bands;
}

std::vector<std::size_t> ascending_band_order(std::span<const double> nm,
                                              const std::function<void(std::size_t, std::size_t)>& repeated) {
  std::vector<std::size_t> all(nm.size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  return ascending_band_order(nm, std::move(all), repeated);
}

WavelengthGrid WavelengthGrid::range(double first, double last, double step) {
  if (!(step > 0) || !(last >= first) || !(first > 0) || !std::isfinite(last))
    throw UsageError("wavelength range " + num(first) + ":" + num(last) + ":" + num(step) +
                     " is invalid; need 0 < FIRST <= LAST and STEP > 0");
  const double count = std::floor((last - first) / step + 1e-3) + 1;
  if (count > 1e6)
    throw UsageError("wavelength range " + num(first) + ":" + num(last) + ":" + num(step) +
                     " has more than a million bands");
  std::vector<double> nm;
  for (std::size_t i = 0; i < static_cast<std::size_t>(count); ++i) nm.push_back(first + step * double(i));
  return WavelengthGrid(std::move(nm));
}

WavelengthGrid WavelengthGrid::parse(std::string_view spec) {
  if (spec.find(':') != std::string_view::npos) {
    std::vector<double> parts;
    std::size_t start = 0;
    while (true) {
      std::size_t colon = spec.find(':', start);
      parts.push_back(parse_number(spec.substr(start, colon - start), spec));
      if (colon == std::string_view::npos) break;
      start = colon + 1;
    }
    if (parts.size() != 3)
      throw UsageError("wavelengths '" + std::string(spec) + "': use FIRST:LAST:STEP, e.g. 420:720:10");
    return range(parts[0], parts[1], parts[2]);
  }
  std::vector<double> nm;
  std::size_t start = 0;
  while (true) {
    std::size_t comma = spec.find(',', start);
    nm.push_back(parse_number(spec.substr(start, comma - start), spec));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  try {
    return WavelengthGrid(std::move(nm), "wavelengths '" + std::string(spec) + "'");
  } catch (const InputError& e) {
    throw UsageError(e.what());
  }
}

bool WavelengthGrid::approx_equal(const WavelengthGrid& other, double tol_nm) const {
  if (size() != other.size()) return false;
  for (std::size_t i = 0; i < size(); ++i)
    if (std::abs(nm_[i] - other.nm_[i]) > tol_nm) return false;
  return true;
}

bool WavelengthGrid::uniform() const {
  if (size() < 3) return true;
  const double s = nm_[1] - nm_[0];
  for (std::size_t i = 2; i < size(); ++i)
    if (std::abs((nm_[i] - nm_[i - 1]) - s) > 1e-6) return false;
  return true;
}

double WavelengthGrid::step() const { return size() < 2 ? 0.0 : nm_[1] - nm_[0]; }

std::size_t WavelengthGrid::nearest(double nm) const {
  std::size_t best = 0;
  for (std::size_t b = 1; b < nm_.size(); ++b)
    if (std::abs(nm_[b] - nm) < std::abs(nm_[best] - nm)) best = b;
  return best;
}

std::string WavelengthGrid::describe() const {
  std::ostringstream s;
  s << size() << (size() == 1 ? " band" : " bands");
  if (empty()) return s.str();
  s << ' ' << front();
  if (size() > 1) s << '-' << back();
  s << " nm";
  if (size() > 1) {
    if (uniform())
      s << " step " << step();
    else
      s << " (irregular)";
  }
  return s.str();
}

Eigen::MatrixXd resample_matrix(const WavelengthGrid& from, const WavelengthGrid& to, std::string_view context) {
  if (from.empty()) throw UsageError(std::string(context) + ": source grid is empty");
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(Eigen::Index(to.size()), Eigen::Index(from.size()));
  const double tol = 1e-6;
  for (std::size_t i = 0; i < to.size(); ++i) {
    const double w = to[i];
    if (w < from.front() - tol || w > from.back() + tol)
      throw InputError(std::string(context) + ": " + num(w) + " nm lies outside the data's " + from.describe() +
                       "; extrapolation is refused, choose target wavelengths inside " + num(from.front()) + "-" +
                       num(from.back()) + " nm");
    std::size_t j = 0;
    while (j + 1 < from.size() && from[j + 1] < w - tol) ++j;
    if (j + 1 >= from.size() || std::abs(w - from[j]) <= tol) {
      r(Eigen::Index(i), Eigen::Index(std::min(j, from.size() - 1))) = 1.0;
    } else if (std::abs(w - from[j + 1]) <= tol) {
      r(Eigen::Index(i), Eigen::Index(j + 1)) = 1.0;
    } else {
      const double t = (w - from[j]) / (from[j + 1] - from[j]);
      r(Eigen::Index(i), Eigen::Index(j)) = 1.0 - t;
      r(Eigen::Index(i), Eigen::Index(j + 1)) = t;
    }
  }
  return r;
}

Eigen::VectorXd sample_tabulated(std::span<const double> x, std::span<const double> y, const WavelengthGrid& grid) {
  if (x.size() != y.size() || x.size() < 2)
    throw UsageError("sample_tabulated: need matching x and y with at least two points");
  Eigen::VectorXd out(Eigen::Index(grid.size()));
  std::size_t j = 0;
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const double w = grid[i];
    if (w < x.front() || w > x.back()) {
      out[Eigen::Index(i)] = 0.0;
      continue;
    }
    while (j + 2 < x.size() && x[j + 1] < w) ++j;
    while (j > 0 && x[j] > w) --j;
    const double t = (w - x[j]) / (x[j + 1] - x[j]);
    out[Eigen::Index(i)] = (1.0 - t) * y[j] + t * y[j + 1];
  }
  return out;
}

Eigen::VectorXd trapezoid_weights(const WavelengthGrid& grid) {
  Eigen::VectorXd w = Eigen::VectorXd::Zero(Eigen::Index(grid.size()));
  if (grid.size() == 1) w[0] = 1.0;
  for (std::size_t i = 0; i + 1 < grid.size(); ++i) {
    const double h = 0.5 * (grid[i + 1] - grid[i]);
    w[Eigen::Index(i)] += h;
    w[Eigen::Index(i + 1)] += h;
  }
  return w;
}

}  // namespace specula
