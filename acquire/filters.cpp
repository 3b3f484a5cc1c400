#include "specula/acquire/filters.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::acquire {

double FilterSet::at(std::size_t k, double l) const {
  if (nm.empty() || l < nm.front() || l > nm.back()) return 0;
  const auto i = std::size_t(std::upper_bound(nm.begin(), nm.end(), l) - nm.begin());
  if (i >= nm.size()) return transmission[k].back();
  const double t = (l - nm[i - 1]) / (nm[i] - nm[i - 1]);
  return transmission[k][i - 1] + t * (transmission[k][i] - transmission[k][i - 1]);
}

namespace {

std::vector<std::string_view> split_commas(std::string_view line) {
  std::vector<std::string_view> cells;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    cells.push_back(trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) return cells;
    start = comma + 1;
  }
}

double parse_number(std::string_view cell, const std::string& where) {
  double v = 0;
  const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), v);
  if (ec != std::errc() || end != cell.data() + cell.size() || cell.empty() || !std::isfinite(v))
    throw InputError(where + ": '" + printable(cell) + "' is not a number");
  return v;
}

}  // namespace

FilterSet parse_filters_csv(std::string_view text, const std::string& source) {
  FilterSet f;
  std::size_t line_no = 0, pos = 0;
  bool header = false;
  while (pos <= text.size()) {
    const std::size_t eol = std::min(text.find('\n', pos), text.size());
    const std::string_view line = trim(text.substr(pos, eol - pos));
    pos = eol + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') continue;
    const std::string where = fmt::format("{}:{}", source, line_no);
    const auto cells = split_commas(line);
    if (!header) {
      if (cells.size() < 2)
        throw InputError(where + ": the header must be wavelength_nm followed by one column per filter");
      for (std::size_t c = 1; c < cells.size(); ++c) {
        if (cells[c].empty()) throw InputError(where + ": filter " + std::to_string(c) + " has no name");
        if (std::any_of(cells[c].begin(), cells[c].end(), [](char ch) { return (ch >= 0 && ch < 0x20) || ch == 0x7f; }))
          throw InputError(where + ": filter name '" + printable(cells[c]) + "' holds control characters");
        f.names.emplace_back(cells[c]);
      }
      f.transmission.resize(f.names.size());
      header = true;
      continue;
    }
    if (cells.size() != f.names.size() + 1)
      throw InputError(fmt::format("{}: {} values; the header names a wavelength and {} filters", where, cells.size(),
                                   f.names.size()));
    const double l = parse_number(cells[0], where);
    if (!(l > 0) || (!f.nm.empty() && !(l > f.nm.back())))
      throw InputError(where + ": wavelength " + num(l) + " nm; wavelengths must be positive and increase");
    f.nm.push_back(l);
    for (std::size_t c = 1; c < cells.size(); ++c) {
      const double t = parse_number(cells[c], where);
      if (t < 0 || t > 1)
        throw InputError(where + ": filter '" + f.names[c - 1] + "' transmits " + num(t) +
                         "; a transmission is 0 to 1");
      f.transmission[c - 1].push_back(t);
    }
  }
  if (!header) throw InputError(source + ": no header line (wavelength_nm,NAME,...)");
  if (f.nm.size() < 2) throw InputError(source + ": fewer than two wavelengths tabulated");
  return f;
}

FilterSet read_filters_csv(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open the filter file");
  std::ostringstream s;
  s << in.rdbuf();
  return parse_filters_csv(s.str(), path.string());
}

void write_filters_csv(const std::filesystem::path& path, const FilterSet& f) {
  const std::string where = "write_filters_csv(" + path.string() + ")";
  if (f.size() == 0 || f.names.size() != f.size() || f.nm.size() < 2)
    throw UsageError(where + ": one name per filter, at least one filter and two wavelengths");
  for (std::size_t i = 0; i < f.nm.size(); ++i)
    if (!(f.nm[i] > 0) || !std::isfinite(f.nm[i]) || (i > 0 && !(f.nm[i] > f.nm[i - 1])))
      throw UsageError(where + ": wavelength " + num(f.nm[i]) + " nm; wavelengths must be positive and increase");
  for (std::size_t k = 0; k < f.size(); ++k) {
    if (f.names[k].empty() ||
        std::any_of(f.names[k].begin(), f.names[k].end(),
                    [](char ch) { return (ch >= 0 && ch < 0x20) || ch == 0x7f || ch == ','; }) ||
        trim(f.names[k]) != f.names[k])
      throw UsageError(where + ": filter name '" + printable(f.names[k]) +
                       "'; a name is not empty, has no commas, control characters or surrounding spaces");
    if (f.transmission[k].size() != f.nm.size())
      throw UsageError(where + ": filter '" + f.names[k] + "' has the wrong number of values");
    for (const double t : f.transmission[k])
      if (!(t >= 0 && t <= 1))
        throw UsageError(where + ": filter '" + f.names[k] + "' transmits " + num(t) + "; a transmission is 0 to 1");
  }
  AtomicOutput out(path);
  {
    std::ofstream o(out.temp_path());
    o << "wavelength_nm";
    for (const auto& n : f.names) o << ',' << n;
    o << '\n';
    for (std::size_t i = 0; i < f.nm.size(); ++i) {
      o << num(f.nm[i]);
      for (const auto& t : f.transmission) o << ',' << fmt::format("{:.6f}", t[i]);
      o << '\n';
    }
    if (!o) throw LibraryError(out.temp_path().string() + ": cannot write the filter file");
  }
  out.commit();
}

void check_filters(const FilterSet& f, std::span<const double> bands, const std::string& source) {
  if (f.size() == 0 || f.names.size() != f.size()) throw InputError(source + ": no filters");
  for (std::size_t k = 0; k < f.size(); ++k) {
    if (f.transmission[k].size() != f.nm.size())
      throw InputError(source + ": filter '" + f.names[k] + "' has the wrong number of values");
    for (const double t : f.transmission[k])
      if (!(t >= 0 && t <= 1))
        throw InputError(source + ": filter '" + f.names[k] + "' transmits " + num(t) + "; a transmission is 0 to 1");
  }
  if (!bands.empty() && (f.nm.empty() || f.nm.front() > bands.front() || f.nm.back() < bands.back()))
    throw InputError(source + ": the filters are tabulated over " +
                     (f.nm.empty() ? "nothing" : num(f.nm.front()) + "-" + num(f.nm.back()) + " nm") +
                     "; the bands need " + num(bands.front()) + "-" + num(bands.back()) + " nm");
  for (std::size_t k = 0; k < f.size(); ++k) {
    double peak = 0;
    for (std::size_t i = 0; i < f.nm.size(); ++i)
      if (bands.empty() || (f.nm[i] >= bands.front() && f.nm[i] <= bands.back()))
        peak = std::max(peak, f.transmission[k][i]);
    if (!(peak > 0)) throw InputError(source + ": filter '" + f.names[k] + "' passes no light within the bands");
  }
}

double filter_roughness(const FilterSet& f) {
  double worst = 0;
  for (const auto& t : f.transmission) {
    const double peak = *std::max_element(t.begin(), t.end());
    if (!(peak > 0)) continue;
    for (std::size_t i = 1; i + 1 < t.size(); ++i) {
      const double h0 = f.nm[i] - f.nm[i - 1], h1 = f.nm[i + 1] - f.nm[i];
      const double d2 = 2 * ((t[i + 1] - t[i]) / h1 - (t[i] - t[i - 1]) / h0) / (h0 + h1);
      worst = std::max(worst, std::abs(d2) / peak);
    }
  }
  return worst;
}

namespace {

// hat_b(l): 1 at band b, linear to 0 at its neighbours; the end hats stay 1 beyond the end bands.
double hat(std::span<const double> bands, std::size_t b, double l) {
  const double x = bands[b];
  if (l <= x) {
    if (b == 0) return 1.0;
    const double a = bands[b - 1];
    return l <= a ? 0.0 : (l - a) / (x - a);
  }
  if (b + 1 == bands.size()) return 1.0;
  const double c = bands[b + 1];
  return l >= c ? 0.0 : (c - l) / (c - x);
}

double legendre(int d, double x) {
  double p0 = 1, p1 = x;
  if (d == 0) return p0;
  for (int n = 1; n < d; ++n) {
    const double p2 = ((2 * n + 1) * x * p1 - n * p0) / (n + 1);
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

}  // namespace

std::vector<Eigen::MatrixXd> filter_system(const FilterSet& f, std::span<const double> bands, const Tabulated& s,
                                           int terms) {
  if (bands.empty() || terms < 1 || terms > 4 || f.size() == 0)
    throw UsageError("filter_system: bands, filters and 1 to 4 response terms");
  const Eigen::Index K = Eigen::Index(f.size()), B = Eigen::Index(bands.size());
  std::vector<Eigen::MatrixXd> a(std::size_t(terms), Eigen::MatrixXd::Zero(K, B));
  const double mid = 0.5 * (bands.front() + bands.back()), half = std::max(1.0, 0.5 * (bands.back() - bands.front()));
  std::vector<double> weight(static_cast<std::size_t>(B));
  // Simpson on pieces of at most 1 nm of each tabulation interval (the curves and the hats are piecewise linear).
  for (std::size_t q = 0; q + 1 < f.nm.size(); ++q) {
    const int pieces = std::max(1, int(std::ceil(f.nm[q + 1] - f.nm[q])));
    const double h = (f.nm[q + 1] - f.nm[q]) / pieces;
    for (int p = 0; p < pieces; ++p)
      for (int node = 0; node < 3; ++node) {
        const double l = f.nm[q] + (p + 0.5 * node) * h, w = h / 6 * (node == 1 ? 4 : 1);
        const double sl = s.at(l) * w, x = (l - mid) / half;
        for (Eigen::Index b = 0; b < B; ++b) weight[std::size_t(b)] = hat(bands, std::size_t(b), l);
        for (Eigen::Index k = 0; k < K; ++k) {
          const double t = f.at(std::size_t(k), l) * sl;
          if (t == 0) continue;
          for (int d = 0; d < terms; ++d) {
            const double td = t * legendre(d, x);
            for (Eigen::Index b = 0; b < B; ++b) a[std::size_t(d)](k, b) += td * weight[std::size_t(b)];
          }
        }
      }
  }
  return a;
}

Eigen::MatrixXd fit_filter_response(const std::vector<Eigen::MatrixXd>& system, const Eigen::MatrixXd& measured,
                                    const Eigen::MatrixXd& reflectance) {
  if (system.empty() || measured.rows() < 1 || measured.rows() != reflectance.rows() ||
      measured.cols() != system[0].rows() || reflectance.cols() != system[0].cols())
    throw UsageError("filter calibration: targets x filters measurements and targets x bands reflectances");
  if (!measured.allFinite() || !reflectance.allFinite()) throw InputError("filter calibration: non-finite target data");
  const Eigen::Index K = measured.cols(), D = Eigen::Index(system.size());
  Eigen::MatrixXd a(K, D);
  for (Eigen::Index k = 0; k < K; ++k) {
    if (!(measured.col(k).maxCoeff() > 0))
      throw InputError("filter calibration: filter " + std::to_string(k) + " has no signal on the targets");
    Eigen::MatrixXd g(measured.rows(), D);
    for (Eigen::Index d = 0; d < D; ++d) g.col(d) = reflectance * system[std::size_t(d)].row(k).transpose();
    // Columns scaled to unit norm; directions the targets cannot tell apart (below 1e-4 of the largest) are left
    // at zero rather than fitted with huge cancelling terms.
    Eigen::VectorXd norm = g.colwise().norm().transpose();
    for (Eigen::Index d = 0; d < D; ++d) norm[d] = norm[d] > 0 ? norm[d] : 1;
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
    cod.setThreshold(1e-4);
    cod.compute(g * norm.cwiseInverse().asDiagonal());
    a.row(k) = norm.cwiseInverse().cwiseProduct(cod.solve(Eigen::VectorXd(measured.col(k)))).transpose();
  }
  return a;
}

Eigen::MatrixXd orthonormal_basis(const Eigen::MatrixXd& columns) {
  if (columns.size() == 0) throw UsageError("orthonormal_basis: no columns");
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(columns, Eigen::ComputeThinU);
  const Eigen::VectorXd& sv = svd.singularValues();
  Eigen::Index r = 0;
  while (r < sv.size() && sv[r] > 1e-10 * sv[0]) ++r;
  if (r == 0) throw UsageError("orthonormal_basis: the basis has rank 0");
  return svd.matrixU().leftCols(r);
}

Eigen::MatrixXd filter_recovery(const Eigen::MatrixXd& system, const Eigen::MatrixXd& basis, double ridge) {
  const Eigen::Index B = system.cols();
  if (B == 0 || (basis.size() && basis.rows() != B) || !(ridge >= 0))
    throw UsageError("filter_recovery: a K x B system, a B x r basis and a ridge >= 0");
  const Eigen::MatrixXd u = basis.size() ? orthonormal_basis(basis) : Eigen::MatrixXd::Identity(B, B);
  const Eigen::MatrixXd m = system * u;
  Eigen::MatrixXd g = m.transpose() * m;
  const double alpha = ridge * g.trace() / double(g.rows());
  g.diagonal().array() += alpha;
  if (alpha > 0) return u * g.ldlt().solve(m.transpose());
  return u * g.completeOrthogonalDecomposition().solve(m.transpose());
}

Eigen::MatrixXd filter_wiener_recovery(const Eigen::MatrixXd& system, const Eigen::MatrixXd& second_moment,
                                       const Eigen::VectorXd& noise) {
  const Eigen::Index B = system.cols(), K = system.rows();
  if (B == 0 || second_moment.rows() != B || second_moment.cols() != B || noise.size() != K ||
      !(noise.array() >= 0).all())
    throw UsageError("filter_wiener_recovery: a K x B system, a B x B second moment and K noise levels >= 0");
  const Eigen::MatrixXd ma = second_moment * system.transpose();
  Eigen::MatrixXd g = system * ma;
  g.diagonal() += noise.array().square().matrix();
  // Directions of the readings the prior and the noise leave empty are dropped, not inverted.
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
  cod.setThreshold(1e-12);
  cod.compute(g);
  return cod.solve(Eigen::MatrixXd(ma.transpose())).transpose();
}

Eigen::MatrixXd filter_wiener_posterior(const Eigen::MatrixXd& system, const Eigen::MatrixXd& second_moment,
                                        const Eigen::VectorXd& noise) {
  const Eigen::MatrixXd r = filter_wiener_recovery(system, second_moment, noise);
  const Eigen::MatrixXd c = second_moment - r * (system * second_moment);
  return 0.5 * (c + c.transpose());
}

Eigen::MatrixXd filter_ridge_posterior(const Eigen::MatrixXd& system, const Eigen::MatrixXd& basis, double ridge) {
  filter_recovery(system, basis, ridge);
  const Eigen::Index B = system.cols();
  const Eigen::MatrixXd u = basis.size() ? orthonormal_basis(basis) : Eigen::MatrixXd::Identity(B, B);
  const Eigen::MatrixXd m = system * u;
  Eigen::MatrixXd g = m.transpose() * m;
  g.diagonal().array() += ridge * g.trace() / double(g.rows());
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
  cod.setThreshold(1e-12);
  cod.compute(g);
  const Eigen::MatrixXd c = u * cod.solve(Eigen::MatrixXd(u.transpose()));
  return 0.5 * (c + c.transpose());
}

void nonnegative_spectrum(const Eigen::MatrixXd& posterior, Eigen::Ref<Eigen::VectorXd> x) {
  const Eigen::Index B = x.size();
  if (posterior.rows() != B || posterior.cols() != B)
    throw UsageError("nonnegative_spectrum: a B x B posterior for a spectrum of B bands");
  if (B == 0 || x.minCoeff() >= 0) return;
  const Eigen::VectorXd mean = x;
  // A tiny ridge keeps the held bands' block invertible where the posterior is (nearly) singular.
  const double jitter = 1e-12 * std::max(posterior.trace() / double(B), 1e-300);
  const double tol = 1e-12 * std::max(mean.cwiseAbs().maxCoeff(), 1e-300);
  std::vector<Eigen::Index> held;
  std::vector<char> is_held(std::size_t(B), 0);
  Eigen::VectorXd nu;
  // Lawson-Hanson's order: hold the most negative free band at zero; release the held band whose multiplier says
  // the minimum lies inside; stop when neither exists. y = mean + C[:, S] nu with nu = -C_SS^-1 mean_S puts y_S = 0
  // and is the minimum on that face; nu is the gradient on S.
  for (Eigen::Index step = 0; step < 4 * B; ++step) {
    if (held.empty()) {
      x = mean;
    } else {
      Eigen::MatrixXd css = posterior(held, held);
      css.diagonal().array() += jitter;
      nu = -css.ldlt().solve(Eigen::VectorXd(mean(held)));
      x = mean + posterior(Eigen::all, held) * nu;
      for (const Eigen::Index b : held) x[b] = 0;
    }
    Eigen::Index worst = -1;
    for (Eigen::Index b = 0; b < B; ++b)
      if (!is_held[std::size_t(b)] && x[b] < -tol && (worst < 0 || x[b] < x[worst])) worst = b;
    if (worst >= 0) {
      held.push_back(worst), is_held[std::size_t(worst)] = 1;
      continue;
    }
    Eigen::Index release = -1;
    const double nu_tol = held.empty() ? 0.0 : 1e-12 * nu.cwiseAbs().maxCoeff();
    for (std::size_t i = 0; i < held.size(); ++i)
      if (nu[Eigen::Index(i)] < -nu_tol && (release < 0 || nu[Eigen::Index(i)] < nu[release]))
        release = Eigen::Index(i);
    if (release < 0) break;
    is_held[std::size_t(held[std::size_t(release)])] = 0;
    held.erase(held.begin() + release);
  }
  x = x.cwiseMax(0.0);
}

}  // namespace specula::acquire
