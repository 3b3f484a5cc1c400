#include "specula/acquire/filter_design.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "specula/acquire/calibrate.h"
#include "specula/acquire/simulate.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula::acquire {

FilterMethod parse_filter_method(const std::string& name) {
  if (name == "nmf") return FilterMethod::nmf;
  if (name == "optimal") return FilterMethod::optimal;
  throw UsageError("filter design method '" + name + "': use nmf (smoothed NMF components) or optimal");
}

FilterSolve parse_filter_solve(const std::string& name) {
  if (name == "ridge") return FilterSolve::ridge;
  if (name == "wiener") return FilterSolve::wiener;
  throw UsageError("filter solve '" + name + "': use wiener (the spectra's second moment as prior) or ridge");
}

void check_filter_design(const FilterDesignOptions& o) {
  if (o.k < 1 || o.k > 31) throw UsageError("filter design: k must be 1 to 31 filters");
  if (!(o.noise >= 0 && o.noise < 1)) throw UsageError("filter design: noise must be in [0, 1)");
  if (!(o.min_throughput >= 0 && o.min_throughput < 1))
    throw UsageError("filter design: the minimum throughput is a fraction of an open filter's light, in [0, 1)");
  if (!(o.ridge >= 0 && o.ridge < 1)) throw UsageError("filter design: ridge must be in [0, 1)");
  if (!(o.colour_weight >= 0 && o.colour_weight <= 1000)) throw UsageError("filter design: colour weight 0 to 1000");
  if (!(o.peak > 0 && o.peak <= 1)) throw UsageError("filter design: peak transmission must be in (0, 1]");
  if (!(o.light_kelvin >= 1000 && o.light_kelvin <= 20000)) throw UsageError("filter design: light 1000-20000 K");
  if (!(o.step_nm >= 0.5 && o.step_nm <= 20)) throw UsageError("filter design: tabulation step 0.5 to 20 nm");
  if (!(o.smooth_nm >= 0 && o.smooth_nm <= 100)) throw UsageError("filter design: smoothing 0 to 100 nm");
}

Tabulated design_sensitivity(double light_kelvin) {
  Tabulated s;
  for (double l = 380; l <= 780.001; l += 2) s.nm.push_back(l);
  const Eigen::VectorXd light = blackbody(light_kelvin, WavelengthGrid(s.nm));
  for (std::size_t i = 0; i < s.nm.size(); ++i)
    s.value.push_back(light[Eigen::Index(i)] * camera_quantum_efficiency(s.nm[i]));
  return s;
}

Eigen::MatrixXd reconstruction_basis(const store::Basis& basis, int k) {
  const Eigen::Index B = Eigen::Index(basis.bands());
  if (k < 1 || basis.components.cols() != B || basis.k() == 0)
    throw UsageError("reconstruction_basis: a basis with components and k >= 1");
  const bool mean = basis.method == "pca" && basis.mean.size() == B;
  const Eigen::Index n = std::min<Eigen::Index>(Eigen::Index(basis.k()), k - (mean ? 1 : 0));
  Eigen::MatrixXd u(B, n + (mean ? 1 : 0));
  if (mean) u.col(0) = basis.mean;
  u.rightCols(n) = basis.components.topRows(n).transpose();
  return u;
}

Eigen::MatrixXd capture_basis(const store::Basis& basis, const Capture& capture, const std::string& label) {
  if (!capture.filters) throw InputError(label + ": a basis is for filter captures; this capture has LCTF bands");
  if (!std::ranges::equal(basis.wavelengths.values(), capture.bands))
    throw InputError(
        fmt::format("{}: the basis has {} bands ({}-{} nm), the capture recovers {} ({}-{} nm); learn the "
                    "basis on the capture's bands",
                    label, basis.bands(), basis.wavelengths.front(), basis.wavelengths.back(), capture.bands.size(),
                    capture.bands.front(), capture.bands.back()));
  return reconstruction_basis(basis, int(capture.filters->size()));
}

Eigen::MatrixXd capture_prior(const store::Basis& basis, const Capture& capture, const std::string& label) {
  capture_basis(basis, capture, label);
  const Eigen::Index B = Eigen::Index(basis.bands());
  if (basis.second_moment.rows() != B || basis.second_moment.cols() != B)
    throw InputError(label + ": the basis stores no second moment for the Wiener solve; learn it again (specula pca " +
                     "or nmf) or use --filter-solve ridge");
  return basis.second_moment;
}

Eigen::MatrixXd colour_rows(std::span<const double> bands) {
  const WavelengthGrid grid(std::vector<double>(bands.begin(), bands.end()));
  const Eigen::MatrixX3d xyz = cmf(grid);
  Eigen::MatrixXd rows(6, Eigen::Index(bands.size()));
  for (const int i : {0, 1}) {
    const Eigen::VectorXd e = illuminant(i == 0 ? "D65" : "A", grid);
    const double white = xyz.col(1).dot(e);
    for (int c = 0; c < 3; ++c) rows.row(3 * i + c) = xyz.col(c).cwiseProduct(e).transpose() / white;
  }
  return rows / std::sqrt(6.0);
}

namespace {

// The K x B system divided by the white reading of an open filter (transmission `peak` everywhere on the bands): every
// filter is exposed as long as that reference, so a filter passing little light reads little and is noisier.
Eigen::MatrixXd normalised_system(const FilterSet& f, std::span<const double> bands, const Tabulated& s, double peak) {
  Eigen::MatrixXd a = filter_system(f, bands, s, 1)[0];
  FilterSet open;
  open.names = {"open"};
  open.nm.assign(bands.begin(), bands.end());
  open.transmission = {std::vector<double>(bands.size(), peak)};
  const double white = filter_system(open, bands, s, 1)[0].sum();
  for (Eigen::Index k = 0; k < a.rows(); ++k)
    if (!(a.row(k).sum() > 0))
      throw InputError("filter design: filter '" + f.names[std::size_t(k)] + "' passes no light");
  return a / white;
}

// Each reading's noise (a: the system over an open filter's white reading): `noise` times the open filter's white
// reading (every filter exposed alike), or times the filter's own white reading (each exposed to fill the sensor, as
// simulate-capture does) but never below `floor` of the open filter's: a filter passing less light than that needs
// an exposure past the camera's longest, so its reading stays below full scale and its noise stops falling.
Eigen::VectorXd reading_noise(const Eigen::MatrixXd& a, double noise, bool per_filter, double floor) {
  if (!per_filter) return Eigen::VectorXd::Constant(a.rows(), noise);
  return noise * a.rowwise().sum().cwiseMax(floor);
}

// The recovery of the design's error model: Wiener with `prior` when it is not empty, else the ridge in `u`.
Eigen::MatrixXd design_recovery(const Eigen::MatrixXd& a, const Eigen::MatrixXd& u, const Eigen::MatrixXd& prior,
                                const Eigen::VectorXd& sigma, double ridge) {
  if (prior.size() == 0) return filter_recovery(a, u, ridge);
  return filter_wiener_recovery(a, prior, sigma);
}

// Mean expected squared error per band over spectra of second moment m (B x B), plus o.colour_weight times that of
// their colour (`colour`: colour_rows).
double mean_squared_error(const Eigen::MatrixXd& a, const Eigen::MatrixXd& u, const Eigen::MatrixXd& m,
                          const Eigen::MatrixXd& colour, const FilterDesignOptions& o) {
  const Eigen::VectorXd sigma = reading_noise(a, o.noise, o.per_filter_exposure, o.min_throughput);
  const Eigen::MatrixXd r =
      design_recovery(a, u, o.solve == FilterSolve::wiener ? m : Eigen::MatrixXd(), sigma, o.ridge);
  const Eigen::MatrixXd e = Eigen::MatrixXd::Identity(a.cols(), a.cols()) - r * a;
  const double spectral = ((e * m * e.transpose()).trace() + (r * sigma.asDiagonal()).squaredNorm()) / double(a.cols());
  if (o.colour_weight == 0) return spectral;
  const Eigen::MatrixXd ce = colour * e;
  return spectral +
         o.colour_weight * ((ce * m * ce.transpose()).trace() + (colour * r * sigma.asDiagonal()).squaredNorm());
}

std::vector<double> design_grid(std::span<const double> bands, double step) {
  std::vector<double> nm;
  for (double l = bands.front(); l < bands.back() - 1e-9; l += step) nm.push_back(l);
  nm.push_back(bands.back());
  return nm;
}

// A super-Gaussian filter from unconstrained parameters: centre, log width, flatness.
void super_gaussian(const double* p, std::span<const double> bands, double peak, const std::vector<double>& nm,
                    std::vector<double>& t) {
  const double mid = 0.5 * (bands.front() + bands.back()), half = 0.5 * (bands.back() - bands.front());
  const double centre = mid + 1.2 * half * std::tanh(p[0]);
  const double width = std::clamp(std::exp(p[1]), 8.0, 4 * half);
  const double power = 2 + 4 / (1 + std::exp(-p[2]));
  t.resize(nm.size());
  for (std::size_t i = 0; i < nm.size(); ++i)
    t[i] = peak * std::exp(-0.5 * std::pow(std::abs(nm[i] - centre) / width, power));
}

FilterSet named(std::vector<double> nm, std::vector<std::vector<double>> t, const char* prefix) {
  FilterSet f;
  f.nm = std::move(nm);
  f.transmission = std::move(t);
  for (std::size_t k = 0; k < f.size(); ++k) f.names.push_back(fmt::format("{}{}", prefix, k + 1));
  return f;
}

FilterSet nmf_filters(const store::Basis& basis, const FilterDesignOptions& o) {
  if (basis.method != "nmf") throw UsageError("filter design: --method nmf needs an NMF basis (specula nmf)");
  if (int(basis.k()) < o.k)
    throw UsageError(
        fmt::format("filter design: the NMF basis has {} components; {} filters need as many", basis.k(), o.k));
  const std::vector<double> bands(basis.wavelengths.values().begin(), basis.wavelengths.values().end());
  const std::vector<double> nm = design_grid(bands, o.step_nm);
  std::vector<std::vector<double>> curves;
  for (int k = 0; k < o.k; ++k) {
    const Eigen::VectorXd c = basis.components.row(k).transpose();
    std::vector<double> t(nm.size());
    for (std::size_t i = 0; i < nm.size(); ++i) {
      double sum = 0, wsum = 0;
      for (std::size_t b = 0; b < bands.size(); ++b) {
        const double d = (bands[b] - nm[i]) / std::max(o.smooth_nm, 1e-9);
        const double w = o.smooth_nm > 0 ? std::exp(-0.5 * d * d) : (std::abs(d) < 1e-6);
        sum += w * std::max(0.0, c[Eigen::Index(b)]), wsum += w;
      }
      t[i] = wsum > 0 ? sum / wsum : Tabulated{bands, std::vector<double>(c.data(), c.data() + c.size())}.at(nm[i]);
    }
    const double peak = *std::max_element(t.begin(), t.end());
    if (!(peak > 0)) throw InputError(fmt::format("filter design: NMF component {} is zero", k + 1));
    for (double& v : t) v = std::max(0.0, v) * o.peak / peak;
    curves.push_back(std::move(t));
  }
  return named(nm, std::move(curves), "nmf");
}

FilterSet optimal_filters(const store::Basis& basis, const Eigen::MatrixXd& training, const FilterDesignOptions& o) {
  const std::vector<double> bands(basis.wavelengths.values().begin(), basis.wavelengths.values().end());
  const std::vector<double> nm = design_grid(bands, o.step_nm);
  const Tabulated s = design_sensitivity(o.light_kelvin);
  const Eigen::MatrixXd u = reconstruction_basis(basis, o.k);
  const Eigen::MatrixXd m = training.transpose() * training / double(training.rows());
  const Eigen::MatrixXd colour = colour_rows(bands);
  const int K = o.k;
  auto build = [&](const Eigen::VectorXd& p) {
    std::vector<std::vector<double>> t{std::size_t(K)};
    for (int k = 0; k < K; ++k) super_gaussian(p.data() + 3 * k, bands, o.peak, nm, t[std::size_t(k)]);
    return named(nm, std::move(t), "opt");
  };
  auto cost = [&](const Eigen::VectorXd& p) {
    try {
      return mean_squared_error(normalised_system(build(p), bands, s, 1.0), u, m, colour, o);
    } catch (const Error&) {
      return 1e30;
    }
  };
  // Evenly spaced, overlapping filters to start; then Nelder-Mead, restarted from its result while it improves.
  Eigen::VectorXd p(3 * K), step(3 * K);
  const double half = 0.5 * (bands.back() - bands.front());
  for (int k = 0; k < K; ++k) {
    const double x = -1 + (2 * k + 1.0) / K;  // in (-1, 1)
    p[3 * k] = std::atanh(std::clamp(x / 1.2, -0.99, 0.99));
    p[3 * k + 1] = std::log(std::max(10.0, 1.2 * half / K));
    p[3 * k + 2] = 0;
    step[3 * k] = 0.3, step[3 * k + 1] = 0.3, step[3 * k + 2] = 1.0;
  }
  double best = cost(p);
  for (int round = 0; round < 4; ++round) {
    const SimplexResult r = nelder_mead(cost, p, step, 600 * K, 1e-14);
    const bool better = r.value < best * (1 - 1e-4);
    if (r.value < best) best = r.value, p = r.x;
    if (!better) break;
    step *= 0.5;
  }
  return build(p);
}

}  // namespace

FilterError expected_filter_error(const FilterSet& f, std::span<const double> bands, const Tabulated& s,
                                  const Eigen::MatrixXd& basis, const Eigen::MatrixXd& spectra, double noise,
                                  double ridge, const Eigen::MatrixXd& prior, bool per_filter_exposure,
                                  double min_throughput) {
  if (spectra.cols() != Eigen::Index(bands.size()) || spectra.rows() == 0)
    throw UsageError("expected_filter_error: spectra (rows) on the bands");
  const Eigen::MatrixXd a = normalised_system(f, bands, s, 1.0);
  const Eigen::VectorXd sigma = reading_noise(a, noise, per_filter_exposure, min_throughput);
  const Eigen::MatrixXd r = design_recovery(a, basis, prior, sigma, ridge);
  const Eigen::MatrixXd e = spectra.transpose() - r * (a * spectra.transpose());
  const double b = double(bands.size()), noise2 = (r * sigma.asDiagonal()).squaredNorm();
  std::vector<double> rms(std::size_t(spectra.rows()));
  for (Eigen::Index i = 0; i < spectra.rows(); ++i)
    rms[std::size_t(i)] = std::sqrt((e.col(i).squaredNorm() + noise2) / b);
  FilterError out;
  out.spectra = rms.size();
  for (const double v : rms) out.rms_mean += v / double(rms.size());
  out.rms_max = *std::max_element(rms.begin(), rms.end());
  std::nth_element(rms.begin(), rms.begin() + std::ptrdiff_t(rms.size() / 2), rms.end());
  out.rms_median = rms[rms.size() / 2];
  out.noise_rms = std::sqrt(noise2 / b);
  return out;
}

std::vector<double> filter_throughput(const FilterSet& f, std::span<const double> bands, const Tabulated& s) {
  const Eigen::VectorXd w = normalised_system(f, bands, s, 1.0).rowwise().sum();
  return {w.data(), w.data() + w.size()};
}

FilterSet design_filters(const store::Basis& basis, const Eigen::MatrixXd& training, const FilterDesignOptions& o) {
  check_filter_design(o);
  if (basis.bands() < 2 || training.cols() != Eigen::Index(basis.bands()) || training.rows() == 0)
    throw UsageError("filter design: training spectra (rows) on the basis's wavelengths");
  return o.method == FilterMethod::nmf ? nmf_filters(basis, o) : optimal_filters(basis, training, o);
}

namespace {

Eigen::MatrixXd collection_matrix(const store::Store& s, const std::string& name, const store::Basis& basis) {
  const store::Collection c = s.read_collection(name);
  if (!std::ranges::equal(c.wavelengths.values(), basis.wavelengths.values()))
    throw InputError(
        fmt::format("{}: collection '{}' has {} bands, the basis {} on other wavelengths; import it with "
                    "--wavelengths matching the basis",
                    s.label(), name, c.bands(), basis.bands()));
  Eigen::MatrixXd m(Eigen::Index(c.size()), Eigen::Index(c.bands()));
  for (std::size_t i = 0; i < c.size(); ++i)
    for (std::size_t b = 0; b < c.bands(); ++b) m(Eigen::Index(i), Eigen::Index(b)) = c.values[i * c.bands() + b];
  return m;
}

}  // namespace

FilterDesign design_filters(const store::Store& s, const std::string& basis_name, const std::string& train,
                            const std::string& test, const FilterDesignOptions& o) {
  check_filter_design(o);
  const store::Basis basis = s.read_basis(basis_name);
  FilterDesign d;
  d.training_name = train;
  if (d.training_name.empty()) {
    if (!basis.source.starts_with("collection "))
      throw UsageError(s.label() + ": basis '" + basis_name + "' was learned from " + basis.source +
                       ", not a collection; name the training collection");
    d.training_name = basis.source.substr(11);
  }
  Eigen::MatrixXd training = collection_matrix(s, d.training_name, basis), held_out;
  if (test.empty()) {
    std::vector<Eigen::Index> fit, out;
    for (Eigen::Index i = 0; i < training.rows(); ++i) (i % 5 == 4 ? out : fit).push_back(i);
    if (out.empty())
      throw InputError(s.label() + ": collection '" + d.training_name +
                       "' has too few spectra to hold "
                       "out every fifth; name a test collection");
    held_out = training(out, Eigen::all);
    training = Eigen::MatrixXd(training(fit, Eigen::all));
    d.held_out_name = d.training_name + " (every fifth spectrum)";
  } else {
    held_out = collection_matrix(s, test, basis);
    d.held_out_name = test;
  }
  d.bands.assign(basis.wavelengths.values().begin(), basis.wavelengths.values().end());
  d.filters = design_filters(basis, training, o);
  const Tabulated sens = design_sensitivity(o.light_kelvin);
  const Eigen::MatrixXd u = reconstruction_basis(basis, o.k);
  const Eigen::MatrixXd prior = o.solve == FilterSolve::wiener
                                    ? Eigen::MatrixXd(training.transpose() * training / double(training.rows()))
                                    : Eigen::MatrixXd();
  d.training = expected_filter_error(d.filters, d.bands, sens, u, training, o.noise, o.ridge, prior,
                                     o.per_filter_exposure, o.min_throughput);
  d.held_out = expected_filter_error(d.filters, d.bands, sens, u, held_out, o.noise, o.ridge, prior,
                                     o.per_filter_exposure, o.min_throughput);
  return d;
}

}  // namespace specula::acquire
