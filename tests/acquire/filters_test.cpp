// Broadband filters: the CSV reader's refusals, the forward model against closed forms, the calibration on targets
// recovering known responses, exact recovery of a spectrum in the basis's span, narrow filters reproducing the
// LCTF's factored model (eq 4.6), designed curves that are transmissions (non-negative, at most 1, smooth), and the
// default colour weight lowering held-out Munsell chips' CIEDE2000 (../shared).
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <cmath>
#include <random>

#include "acquire/small_rig.h"
#include "specula/acquire/filter_design.h"
#include "specula/acquire/filters.h"
#include "specula/acquire/spectral.h"
#include "specula/core/cie.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/store/io/csv.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;

namespace {

using test::bands_420_720;

// K Gaussian filters of width `sigma` spread over 420-720 nm, tabulated every `step` nm over 400-740.
FilterSet gaussians(int k, double sigma, double step = 2) {
  FilterSet f;
  for (double l = 400; l <= 740.001; l += step) f.nm.push_back(l);
  for (int j = 0; j < k; ++j) {
    const double c = 420 + 300.0 * (j + 0.5) / k;
    f.names.push_back("g" + std::to_string(j));
    std::vector<double> t;
    for (const double l : f.nm) t.push_back(0.9 * std::exp(-0.5 * std::pow((l - c) / sigma, 2)));
    f.transmission.push_back(t);
  }
  return f;
}

Tabulated smooth_light() {
  Tabulated s;
  for (double l = 380; l <= 780; l += 5) {
    s.nm.push_back(l);
    s.value.push_back(0.4 + l / 800);
  }
  return s;
}

// n smooth random reflectances on 420-720 nm (rows): a base, a bump of random place and width and a broad one.
Eigen::MatrixXd smooth_spectra(Eigen::Index n, unsigned seed) {
  const std::vector<double> bands = bands_420_720();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::MatrixXd spectra(n, Eigen::Index(bands.size()));
  for (Eigen::Index i = 0; i < n; ++i) {
    const double c1 = 420 + 300 * u(rng), c2 = 420 + 300 * u(rng), w1 = 30 + 80 * u(rng), base = 0.05 + 0.2 * u(rng);
    for (Eigen::Index b = 0; b < spectra.cols(); ++b) {
      const double l = bands[std::size_t(b)];
      spectra(i, b) =
          base + 0.6 * std::exp(-0.5 * std::pow((l - c1) / w1, 2)) + 0.2 * std::exp(-0.5 * std::pow((l - c2) / 60, 2));
    }
  }
  return spectra;
}

// A PCA basis of the spectra (rows on 420-720 nm): their mean and first k components.
store::Basis pca_basis(const Eigen::MatrixXd& spectra, Eigen::Index k) {
  store::Basis pca;
  pca.method = "pca";
  pca.wavelengths = WavelengthGrid(bands_420_720());
  pca.mean = spectra.colwise().mean().transpose();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(spectra.rowwise() - pca.mean.transpose(), Eigen::ComputeThinV);
  pca.components = svd.matrixV().leftCols(k).transpose();
  return pca;
}

// The design's model of filters `f` (written out here, not through the design's code): the K x B system over an open
// filter's white reading, the Wiener recovery with prior `m` and each filter's noise (o.noise times its white reading,
// never below o.min_throughput), and that noise.
struct WienerModel {
  Eigen::MatrixXd a, r;
  Eigen::VectorXd sigma;
};
WienerModel wiener_model(const FilterSet& f, const std::vector<double>& bands, const Eigen::MatrixXd& m,
                         const FilterDesignOptions& o) {
  const Tabulated s = design_sensitivity(o.light_kelvin);
  const std::vector<double> w = filter_throughput(f, bands, s);
  Eigen::VectorXd sigma(Eigen::Index(w.size()));
  for (std::size_t k = 0; k < w.size(); ++k) sigma[Eigen::Index(k)] = o.noise * std::max(w[k], o.min_throughput);
  FilterSet open;
  open.names = {"open"};
  open.nm = bands;
  open.transmission = {std::vector<double>(bands.size(), 1.0)};
  const Eigen::MatrixXd a = filter_system(f, bands, s, 1)[0] / filter_system(open, bands, s, 1)[0].sum();
  return {a, filter_wiener_recovery(a, m, sigma), sigma};
}

std::string error_of(const std::string& text) {
  try {
    parse_filters_csv(text, "f.csv");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(FilterCsv, RoundTripAndOneLineRefusals) {
  const FilterSet f = parse_filters_csv("wavelength_nm,a,b\n# comment\n400,0,0.5\n410,1,0.25\n420,0.5,0\n", "f.csv");
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f.names[1], "b");
  EXPECT_DOUBLE_EQ(f.at(0, 405), 0.5);
  EXPECT_DOUBLE_EQ(f.at(1, 415), 0.125);
  EXPECT_EQ(f.at(0, 399), 0.0);
  EXPECT_EQ(f.at(0, 421), 0.0);
  EXPECT_NE(error_of("wavelength_nm,a\n400,-0.1\n410,0.2\n").find("f.csv:2: filter 'a' transmits -0.1"),
            std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n400,1.5\n410,0.2\n").find("f.csv:2"), std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n410,0.1\n400,0.2\n").find("f.csv:3: wavelength 400 nm"), std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n400,0.1,0.3\n").find("f.csv:2: 3 values"), std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n400,x\n").find("'x' is not a number"), std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n400,nan\n410,0\n").find("is not a number"), std::string::npos);
  EXPECT_NE(error_of("").find("no header"), std::string::npos);
  EXPECT_NE(error_of("wavelength_nm,a\n400,0.3\n").find("fewer than two"), std::string::npos);
  // Wavelengths that do not cover the bands, and a filter dark on them.
  const std::vector<double> bands = bands_420_720();
  try {
    check_filters(f, bands, "f.csv");
    FAIL() << "a 400-420 nm tabulation covers 420-720 nm bands";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f.csv: the filters are tabulated over 400-420 nm"), std::string::npos);
  }
  FilterSet dark = gaussians(2, 30);
  std::fill(dark.transmission[1].begin(), dark.transmission[1].end(), 0.0);
  EXPECT_THROW(check_filters(dark, bands, "f.csv"), InputError);
}

TEST(FilterSystem, ClosedFormsForAnOpenFilter) {
  // T = 1 over 400-740, s = 1: row b is the integral of hat_b over 400-740 (the end hats stay 1 beyond the bands).
  FilterSet open;
  open.names = {"open"};
  open.nm = {400, 740};
  open.transmission = {{1, 1}};
  const std::vector<double> bands = bands_420_720();
  const Tabulated one{{300, 800}, {1, 1}};
  const auto a = filter_system(open, bands, one, 2);
  for (std::size_t b = 1; b + 1 < bands.size(); ++b) EXPECT_NEAR(a[0](0, Eigen::Index(b)), 10.0, 1e-9);
  EXPECT_NEAR(a[0](0, 0), 20 + 5, 1e-9);
  EXPECT_NEAR(a[0](0, 30), 20 + 5, 1e-9);
  // P1 = (l - 570) / 150 is odd about 570 nm: a constant spectrum reads 0 through it.
  EXPECT_NEAR(a[1].sum(), 0.0, 1e-9);
}

TEST(FilterCalibration, RecoversKnownResponsesFromTargets) {
  const std::vector<double> bands = bands_420_720();
  const FilterSet f = gaussians(5, 40);
  const auto system = filter_system(f, bands, smooth_light(), 2);
  Eigen::MatrixXd truth(5, 2);
  truth << 2, 0.3, 1.5, -0.2, 3, 0.1, 0.7, 0, 1.1, 0.4;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  Eigen::MatrixXd reflectance(4, Eigen::Index(bands.size()));
  for (Eigen::Index i = 0; i < reflectance.rows(); ++i)
    for (Eigen::Index b = 0; b < reflectance.cols(); ++b) reflectance(i, b) = u(rng);
  Eigen::MatrixXd measured(4, 5);
  for (Eigen::Index i = 0; i < 4; ++i)
    for (Eigen::Index k = 0; k < 5; ++k)
      measured(i, k) = truth(k, 0) * system[0].row(k).dot(reflectance.row(i)) +
                       truth(k, 1) * system[1].row(k).dot(reflectance.row(i));
  const Eigen::MatrixXd a = fit_filter_response(system, measured, reflectance);
  EXPECT_LT((a - truth).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(FilterRecovery, ASpectrumInTheBasisSpanIsRecoveredExactly) {
  const std::vector<double> bands = bands_420_720();
  const Eigen::MatrixXd a = filter_system(gaussians(6, 35), bands, smooth_light(), 1)[0];
  Eigen::MatrixXd basis(Eigen::Index(bands.size()), 4);
  for (Eigen::Index b = 0; b < basis.rows(); ++b) {
    const double x = (bands[std::size_t(b)] - 570) / 150;
    basis.row(b) << 1, x, x * x, std::sin(3 * x);
  }
  const Eigen::VectorXd spectrum = basis * Eigen::Vector4d(0.4, -0.1, 0.2, 0.05);
  const Eigen::MatrixXd r = filter_recovery(a, basis, 0);
  EXPECT_LT((r * a * spectrum - spectrum).cwiseAbs().maxCoeff(), 1e-10);
  // The ridge trades a little bias for stability: small, but no longer exact.
  const Eigen::MatrixXd ridge = filter_recovery(a, basis, 1e-3);
  const double err = (ridge * a * spectrum - spectrum).cwiseAbs().maxCoeff();
  EXPECT_GT(err, 1e-8);
  EXPECT_LT(err, 0.02);
}

TEST(FilterRecovery, NarrowFiltersOneperBandReproduceTheFactoredModel) {
  // K = B narrow filters (the LCTF's passbands as a filter wheel), no basis, no ridge, one response term: the filter
  // calibration and recovery are the factored model's (eq 4.6, Nystrom eq 4.7) up to quadrature.
  const std::vector<double> bands = bands_420_720();
  FilterSet f;
  for (double l = 400; l <= 740.001; l += 1) f.nm.push_back(l);
  std::vector<Tabulated> lctf;
  for (const double c : bands) {
    std::vector<double> t;
    for (const double l : f.nm) t.push_back(0.5 * std::exp(-0.5 * std::pow((l - c) / 5, 2)));
    f.names.push_back(std::to_string(int(c)));
    f.transmission.push_back(t);
    lctf.push_back({f.nm, t});
  }
  const Tabulated light = smooth_light();
  Eigen::MatrixXd reflectance(2, Eigen::Index(bands.size())), probe(1, Eigen::Index(bands.size()));
  for (Eigen::Index b = 0; b < reflectance.cols(); ++b) {
    const double l = bands[std::size_t(b)];
    reflectance(0, b) = 0.98;
    reflectance(1, b) = 0.05 + 0.5 * std::exp(-std::pow((l - 450) / 45, 2));
    probe(0, b) = 0.2 + 0.6 / (1 + std::exp(-(l - 600) / 12));
  }
  // Readings of the targets and the probe through the model with a camera gain per band.
  const auto system = filter_system(f, bands, light, 1);
  Eigen::VectorXd gain(Eigen::Index(bands.size()));
  for (Eigen::Index b = 0; b < gain.size(); ++b) gain[b] = 1000 * (1 + 0.3 * std::sin(0.2 * double(b)));
  const Eigen::MatrixXd measured = (reflectance * system[0].transpose()) * gain.asDiagonal();
  const Eigen::VectorXd h = gain.asDiagonal() * (system[0] * probe.row(0).transpose());
  const Eigen::MatrixXd a = fit_filter_response(system, measured, reflectance);
  const Eigen::MatrixXd recovery = filter_recovery(a.col(0).asDiagonal() * system[0], Eigen::MatrixXd(), 0);
  const SpectralCalibration factored = fit_factored(bands, light, lctf, measured, reflectance);
  const Eigen::VectorXd ours = recovery * h, theirs = factored.recovery * h;
  EXPECT_LT((ours - probe.row(0).transpose()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((ours - theirs).cwiseAbs().maxCoeff(), 2e-3);
}

TEST(FilterDesign, CurvesAreSmoothBoundedTransmissionsAndTheOptimumBeatsNmf) {
  // Training spectra: smooth random reflectances; a PCA-like basis from their SVD and an NMF-like basis of
  // non-negative bumps.
  const std::vector<double> bands = bands_420_720();
  const Eigen::Index B = Eigen::Index(bands.size());
  const Eigen::MatrixXd spectra = smooth_spectra(300, 5);
  const store::Basis pca = pca_basis(spectra, 6);
  store::Basis nmf;
  nmf.method = "nmf";
  nmf.wavelengths = pca.wavelengths;
  nmf.components.resize(5, B);
  for (Eigen::Index k = 0; k < 5; ++k)
    for (Eigen::Index b = 0; b < B; ++b)
      nmf.components(k, b) = std::exp(-0.5 * std::pow((bands[std::size_t(b)] - 440 - 65.0 * double(k)) / 35, 2)) +
                             0.02 * std::sin(double(b) * 3.1);  // wiggles the smoothing removes
  FilterDesignOptions o;
  o.k = 5;
  o.method = FilterMethod::nmf;
  const FilterSet from_nmf = design_filters(nmf, spectra, o);
  o.method = FilterMethod::optimal;
  o.colour_weight = 0;  // the spectral criterion alone, which e_opt below measures
  const FilterSet optimal = design_filters(pca, spectra, o);
  for (const FilterSet* f : {&from_nmf, &optimal}) {
    ASSERT_EQ(f->size(), 5u);
    EXPECT_NO_THROW(check_filters(*f, bands, "design"));
    for (const auto& t : f->transmission) {
      EXPECT_GE(*std::min_element(t.begin(), t.end()), 0.0);
      EXPECT_LE(*std::max_element(t.begin(), t.end()), o.peak + 1e-12);
    }
    // No curve bends faster than a Gaussian of sigma 8 nm at its peak (1 / 64 per nm^2).
    EXPECT_LT(filter_roughness(*f), 1.0 / 64);
  }
  const Tabulated s = design_sensitivity(o.light_kelvin);
  const Eigen::MatrixXd u5 = reconstruction_basis(pca, 5);
  // The design's own criterion: the Wiener solve with the spectra's second moment, each filter exposed to fill.
  const Eigen::MatrixXd m = spectra.transpose() * spectra / double(spectra.rows());
  const double e_opt = expected_filter_error(optimal, bands, s, u5, spectra, o.noise, o.ridge, m, true).rms_mean;
  const double e_nmf = expected_filter_error(from_nmf, bands, s, u5, spectra, o.noise, o.ridge, m, true).rms_mean;
  EXPECT_LT(e_opt, e_nmf);
  EXPECT_LT(e_opt, 0.03);
  // The Wiener solve is the least expected error of any linear recovery: not above the ridge's on its prior.
  const double e_ridge = expected_filter_error(optimal, bands, s, u5, spectra, o.noise, o.ridge, {}, true).rms_mean;
  EXPECT_LE(e_opt, e_ridge * (1 + 1e-9));
}

// Expected squared error of recovery r for spectra of second moment m and reading noise sigma.
static double wiener_risk(const Eigen::MatrixXd& r, const Eigen::MatrixXd& a, const Eigen::MatrixXd& m,
                          const Eigen::VectorXd& sigma) {
  const Eigen::MatrixXd e = Eigen::MatrixXd::Identity(a.cols(), a.cols()) - r * a;
  return (e * m * e.transpose()).trace() + (r * sigma.asDiagonal()).squaredNorm();
}

TEST(FilterRecovery, WienerIsExactInThePriorsRangeAndMinimisesTheExpectedError) {
  const std::vector<double> bands = bands_420_720();
  const Eigen::Index B = Eigen::Index(bands.size());
  Tabulated s;
  for (double l = 380; l <= 780; l += 2) s.nm.push_back(l), s.value.push_back(1 + 0.002 * (l - 380));
  const Eigen::MatrixXd a = filter_system(gaussians(6, 40), bands, s, 1)[0];
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  Eigen::MatrixXd u(B, 4);
  for (Eigen::Index i = 0; i < u.size(); ++i) u.data()[i] = n01(rng);
  const Eigen::MatrixXd m = u * u.transpose();
  // Without noise, a spectrum in the prior's range (rank 4 < K = 6) comes back exactly.
  const Eigen::MatrixXd r0 = filter_wiener_recovery(a, m, Eigen::VectorXd::Zero(6));
  const Eigen::VectorXd x = u * Eigen::Vector4d(0.3, -0.2, 0.5, 0.1);
  EXPECT_LT((r0 * (a * x) - x).norm(), 1e-9 * x.norm());
  // With noise, any perturbation of the recovery raises the expected error (the risk is convex, its minimum unique).
  const Eigen::MatrixXd full = m + 0.01 * Eigen::MatrixXd::Identity(B, B);
  const Eigen::VectorXd sigma = 0.05 * a.rowwise().sum();
  const Eigen::MatrixXd r = filter_wiener_recovery(a, full, sigma);
  const double best = wiener_risk(r, a, full, sigma);
  for (int t = 0; t < 20; ++t) {
    Eigen::MatrixXd d(B, 6);
    for (Eigen::Index i = 0; i < d.size(); ++i) d.data()[i] = n01(rng);
    d *= 1e-3 * r.norm() / d.norm();
    EXPECT_GT(wiener_risk(r + d, a, full, sigma), best);
  }
  EXPECT_THROW(filter_wiener_recovery(a, full, -sigma), UsageError);
  EXPECT_THROW(filter_wiener_recovery(a, Eigen::MatrixXd::Identity(3, 3), sigma), UsageError);
}

// The non-negative reconstruction against every face of the orthant enumerated: on each set S of bands held at zero
// the posterior's minimum is found by a least-squares solve of its own, kept when feasible; the best of them is the
// constrained minimum.
TEST(FilterRecovery, NonnegativeSpectrumIsTheConstrainedPosteriorMode) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const int B = 6;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::MatrixXd g(B, B + 2);
    for (Eigen::Index i = 0; i < g.size(); ++i) g.data()[i] = normal(rng);
    const Eigen::MatrixXd c = g * g.transpose() / B + 0.05 * Eigen::MatrixXd::Identity(B, B);
    const Eigen::MatrixXd p = c.inverse();
    Eigen::VectorXd mean(B);
    for (int b = 0; b < B; ++b) mean[b] = normal(rng);
    double best = 1e300;
    Eigen::VectorXd expect;
    for (int mask = 0; mask < (1 << B); ++mask) {
      std::vector<Eigen::Index> free;
      for (int b = 0; b < B; ++b)
        if (!(mask >> b & 1)) free.push_back(b);
      // Minimise (y - mean)^T P (y - mean) over y_free with the others zero: P_FF y_F = (P mean)_F.
      Eigen::VectorXd y = Eigen::VectorXd::Zero(B);
      if (!free.empty()) {
        const Eigen::VectorXd rhs = (p * mean)(free);
        y(free) = Eigen::MatrixXd(p(free, free)).colPivHouseholderQr().solve(rhs);
      }
      if (y.minCoeff() < -1e-12) continue;
      const double v = (y - mean).dot(p * (y - mean));
      if (v < best) best = v, expect = y;
    }
    Eigen::VectorXd x = mean;
    nonnegative_spectrum(c, x);
    EXPECT_GE(x.minCoeff(), 0.0);
    EXPECT_LT((x - expect).cwiseAbs().maxCoeff(), 1e-8) << "trial " << trial;
  }
  // A spectrum without negative bands is the linear estimate as it is.
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(B, 0.1, 0.6);
  const Eigen::VectorXd before = x;
  nonnegative_spectrum(Eigen::MatrixXd::Identity(B, B), x);
  EXPECT_EQ(x, before);
  EXPECT_THROW(nonnegative_spectrum(Eigen::MatrixXd::Identity(B + 1, B + 1), x), UsageError);
}

// The Wiener posterior against its closed form for a diagonal prior and one open filter: the variance of band b
// given one reading y = sum_b a_b x_b + noise is m_b - m_b^2 a_b^2 / (sum a^2 m + sigma^2).
TEST(FilterRecovery, WienerPosteriorOfOneReadingMatchesTheClosedForm) {
  const int B = 4;
  Eigen::MatrixXd a(1, B);
  a << 1, 2, 0.5, 1.5;
  const Eigen::VectorXd m = Eigen::Vector4d(0.3, 0.1, 0.2, 0.4), sigma = Eigen::VectorXd::Constant(1, 0.3);
  const Eigen::MatrixXd c = filter_wiener_posterior(a, m.asDiagonal(), sigma);
  const double s = (a.row(0).transpose().array().square() * m.array()).sum() + 0.09;
  for (int i = 0; i < B; ++i)
    for (int j = 0; j < B; ++j)
      EXPECT_NEAR(c(i, j), (i == j ? m[i] : 0.0) - m[i] * a(0, i) * m[j] * a(0, j) / s, 1e-12);
}

// The design's noise floor: throughput against its closed form (filters over 400-740 nm pass light beyond the
// 420-720 nm bands too, where spectra are held constant: under a light linear in l and centred alike, 340 / 300 of an
// open filter on the bands, half of it at half transmission), and a filter below min_throughput is charged the floor's
// noise, not its own (smaller) white reading's.
TEST(FilterDesign, ThroughputAndTheExposureCapsNoiseFloor) {
  const std::vector<double> bands = bands_420_720();
  const Eigen::Index B = Eigen::Index(bands.size());
  FilterSet f;
  f.nm = {400, 740};
  f.names = {"open", "half"};
  f.transmission = {{1, 1}, {0.5, 0.5}};
  const std::vector<double> t = filter_throughput(f, bands, smooth_light());
  EXPECT_NEAR(t[0], 340.0 / 300, 1e-9);
  EXPECT_NEAR(t[1], 170.0 / 300, 1e-9);

  FilterSet g = gaussians(4, 30);
  for (double& v : g.transmission[0]) v *= 1e-3;
  const double dim = filter_throughput(g, bands, smooth_light())[0];
  ASSERT_LT(dim, 0.001);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u01(0.05, 0.9);
  Eigen::MatrixXd spectra(40, B);
  for (Eigen::Index i = 0; i < spectra.size(); ++i) spectra.data()[i] = u01(rng);
  const Eigen::MatrixXd m = spectra.transpose() * spectra / 40.0;
  // The Wiener solve trusts the dim filter less under the floor: its expected error rises.
  auto rms = [&](const FilterSet& fs, double floor) {
    return expected_filter_error(fs, bands, smooth_light(), {}, spectra, 0.01, 0, m, true, floor).rms_mean;
  };
  EXPECT_GT(rms(g, 0.01), 1.01 * rms(g, 0));
  // Filters all above the floor are unaffected by it.
  const FilterSet bright = gaussians(4, 30);
  EXPECT_EQ(rms(bright, 0.01), rms(bright, 0));
  FilterDesignOptions o;
  o.min_throughput = 1;
  EXPECT_THROW(check_filter_design(o), UsageError);
}

TEST(FilterDesign, ColourRowsGiveTheIlluminantsWhitePoints) {
  // A white reflectance's XYZ under D65 and A, against CIE's published white points (2 degree; band sums over
  // 420-720 nm every 10 nm miss the tails, hence 4 %).
  const Eigen::MatrixXd c = colour_rows(bands_420_720()) * std::sqrt(6.0);
  const Eigen::VectorXd white = c * Eigen::VectorXd::Ones(c.cols());
  const double expected[6] = {0.9505, 1.0, 1.0888, 1.0985, 1.0, 0.3558};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(white[i] / expected[i], 1.0, 0.04) << i;
  EXPECT_NEAR(white[1], 1.0, 1e-12);
  EXPECT_NEAR(white[4], 1.0, 1e-12);
  EXPECT_GE(c.minCoeff(), 0.0);
}

TEST(FilterDesign, TheColourTermLowersTheExpectedColourError) {
  const std::vector<double> bands = bands_420_720();
  const Eigen::Index B = Eigen::Index(bands.size());
  const Eigen::MatrixXd spectra = smooth_spectra(200, 7);
  const store::Basis pca = pca_basis(spectra, 4);
  FilterDesignOptions o;
  o.k = 4;
  o.colour_weight = 0;
  const FilterSet spectral = design_filters(pca, spectra, o);
  o.colour_weight = 1;
  const FilterSet coloured = design_filters(pca, spectra, o);
  // Each design's expected error, spectral and of colour, under the Wiener solve with each filter's noise.
  const Eigen::MatrixXd m = spectra.transpose() * spectra / double(spectra.rows()), rows = colour_rows(bands);
  auto errors = [&](const FilterSet& f) {
    const auto [a, r, sigma] = wiener_model(f, bands, m, o);
    const Eigen::MatrixXd e = Eigen::MatrixXd::Identity(B, B) - r * a, ce = rows * e;
    return std::pair{((e * m * e.transpose()).trace() + (r * sigma.asDiagonal()).squaredNorm()) / double(B),
                     (ce * m * ce.transpose()).trace() + (rows * r * sigma.asDiagonal()).squaredNorm()};
  };
  const auto [spectral_s, spectral_c] = errors(spectral);
  const auto [coloured_s, coloured_c] = errors(coloured);
  EXPECT_LT(coloured_c, spectral_c);
  EXPECT_LT(coloured_s + coloured_c, spectral_s + spectral_c);
  EXPECT_LE(spectral_s, coloured_s * (1 + 1e-9));  // the spectral design is the better one on its own criterion
}

TEST(FilterDesign, TheDefaultColourWeightLowersHeldOutMunsellColourDifferences) {
  // The default colour weight (100) was chosen on held-out Munsell chips; this checks the choice against CIEDE2000
  // computed independently of the design's criterion (core/colour.h, trapezoid CMFs, CIELAB): three filters designed
  // on four fifths of the 1269 chips, each held-out fifth chip read without noise and recovered by the Wiener solve.
  SPECULA_REQUIRE_SHARED();
  const store::Collection c =
      store::read_csv_collection(test::shared_dir() / "data" / "reflectance" / "munsell_matt_1269_380-780_5nm.csv");
  const std::vector<double> bands = bands_420_720();
  const Eigen::Index B = Eigen::Index(bands.size());
  std::vector<Eigen::VectorXd> fit, held;
  for (std::size_t i = 0; i < c.size(); ++i) {
    Eigen::VectorXd x(B);
    for (Eigen::Index b = 0; b < B; ++b) x[b] = c.values[i * c.bands() + c.wavelengths.nearest(bands[std::size_t(b)])];
    (i % 5 == 4 ? held : fit).push_back(x);
  }
  Eigen::MatrixXd train(Eigen::Index(fit.size()), B);
  for (std::size_t i = 0; i < fit.size(); ++i) train.row(Eigen::Index(i)) = fit[i].transpose();
  const store::Basis pca = pca_basis(train, 3);
  const Eigen::MatrixXd m = train.transpose() * train / double(train.rows());
  const WavelengthGrid grid(bands);
  const SpectrumToXyz xyz(grid, SpectrumKind::reflectance, illuminant("D65", grid));
  FilterDesignOptions o;
  o.k = 3;
  auto mean_de00 = [&](const FilterSet& f) {
    const auto [a, r, sigma] = wiener_model(f, bands, m, o);
    double sum = 0;
    for (const Eigen::VectorXd& x : held) {
      const Eigen::VectorXd y = r * (a * x);
      sum += ciede2000(xyz_to_lab(xyz.weights() * x, xyz.white()), xyz_to_lab(xyz.weights() * y, xyz.white()));
    }
    return sum / double(held.size());
  };
  const FilterSet chosen = design_filters(pca, train, o);
  o.colour_weight = 1;
  const FilterSet weight_one = design_filters(pca, train, o);
  const double de_chosen = mean_de00(chosen), de_one = mean_de00(weight_one);
  EXPECT_LT(de_chosen, 0.6 * de_one) << de_chosen << " against " << de_one;
}
