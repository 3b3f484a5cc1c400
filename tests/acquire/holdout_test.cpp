// Held-out patches: the chart's layout and its one-line refusals; patches recovered from a capture's images against
// their table (delta passbands: the table itself; filters: a patch inside the basis's span), the ColorChecker of
// ../shared among them when present; and a filter's clamped exposures no longer shifting the scene between lights.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "acquire/small_rig.h"
#include "specula/acquire/filters.h"
#include "specula/acquire/holdout.h"
#include "specula/acquire/pipeline.h"
#include "specula/acquire/simulate.h"
#include "specula/core/error.h"
#include "specula/store/io/csv.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;

namespace {

using test::bands_420_720;

// A table of spectra f(i, nm) on `nm`, named p0, p1, ...
template <class F>
store::Collection table(std::size_t n, const std::vector<double>& nm, F f) {
  store::Collection c;
  c.wavelengths = WavelengthGrid(nm);
  c.provenance.source_file = "patches.csv";
  for (std::size_t i = 0; i < n; ++i) {
    c.names.push_back("p" + std::to_string(i));
    for (const double l : nm) c.values.push_back(float(f(i, l)));
  }
  return c;
}

std::vector<double> every(double first, double last, double step) {
  std::vector<double> v;
  for (double l = first; l <= last + 1e-9; l += step) v.push_back(l);
  return v;
}

// Smooth patches of the kind a chart has: a sloped base and a bump of varied place and width.
double chart_spectrum(std::size_t i, double nm) {
  const double c = 440 + 45.0 * double(i), w = 30 + 10.0 * double(i % 3);
  return 0.08 + 0.0004 * double(i) * (nm - 380) + 0.5 * std::exp(-0.5 * std::pow((nm - c) / w, 2));
}

}  // namespace

TEST(HoldoutChart, DisjointRegionsOnTheImageAndTheTableOnTheBands) {
  // Spectra linear in wavelength, tabulated every 20 nm: linear interpolation onto the bands is exact.
  const auto t = table(7, every(400, 740, 20), [](std::size_t i, double l) { return 0.1 + 0.001 * (l - 400) * i; });
  const std::vector<HoldoutPatch> p = holdout_chart(t, bands_420_720(), 64, 48);
  ASSERT_EQ(p.size(), 7u);
  std::vector<int> owner(64 * 48, -1);
  for (std::size_t i = 0; i < p.size(); ++i) {
    EXPECT_EQ(p[i].name, "p" + std::to_string(i));
    EXPECT_GE(p[i].u0, 0);
    EXPECT_GE(p[i].v0, 0);
    EXPECT_LE(p[i].u1, 64);
    EXPECT_LE(p[i].v1, 48);
    EXPECT_GE(p[i].u1 - p[i].u0, 4);
    EXPECT_GE(p[i].v1 - p[i].v0, 4);
    for (int v = p[i].v0; v < p[i].v1; ++v)
      for (int u = p[i].u0; u < p[i].u1; ++u) {
        EXPECT_EQ(owner[std::size_t(v * 64 + u)], -1) << "patches overlap at " << u << ", " << v;
        owner[std::size_t(v * 64 + u)] = int(i);
      }
    ASSERT_EQ(p[i].reflectance.size(), 31u);
    for (std::size_t b = 0; b < 31; ++b)
      EXPECT_NEAR(p[i].reflectance[b], 0.1 + 0.001 * (420 + 10.0 * double(b) - 400) * double(i), 1e-6);
  }
}

TEST(HoldoutChart, BadTablesAreRefusedWithOneLineNamingTheFile) {
  const std::vector<double> bands = bands_420_720();
  auto refused = [&](const store::Collection& t, int size, const std::string& expect) {
    const std::string e = test::error_of([&] { holdout_chart(t, bands, size, size); });
    EXPECT_NE(e.find("patches.csv: " + expect), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  };
  refused(table(2, every(380, 780, 5), [](std::size_t i, double l) { return i == 1 && l == 500 ? -0.01 : 0.3; }), 64,
          "patch 'p1' has a negative reflectance at 500 nm");
  refused(table(2, every(450, 780, 5), [](std::size_t, double) { return 0.3; }), 64,
          "tabulated on 450-780 nm, which does not cover the bands 420-720 nm");
  refused(table(100, every(380, 780, 5), [](std::size_t, double) { return 0.3; }), 64,
          "100 patches do not fit on a 64 x 64 image");
  refused(table(0, every(380, 780, 5), [](std::size_t, double) { return 0.3; }), 64, "no reflectance spectra");
}

TEST(Holdout, DeltaPassbandsWithoutNoiseRecoverTheTable) {
  // With delta passbands each band reads the patch at its wavelength: the delta model recovers the table's values at
  // the bands, to within quantisation and the HDR merge. The ColorChecker (Ohta 1997) joins when ../shared is there.
  test::ScratchDir dir;
  std::vector<store::Collection> tables = {table(6, every(380, 780, 5), chart_spectrum)};
  if (!test::shared_dir().empty())
    tables.push_back(store::read_csv_collection(test::shared_dir() / "data" / "reflectance" /
                                                "colorchecker24_ohta1997_reflectance.csv"));
  for (std::size_t k = 0; k < tables.size(); ++k) {
    SimulatorOptions o = test::small_rig(80, 50, 3, 30, every(420, 720, 20), false);
    o.passband = Passband::delta;
    o.holdout = tables[k];
    const auto cap_dir = dir / ("cap" + std::to_string(k));
    const Capture cap = simulate_capture(o, cap_dir);
    ASSERT_EQ(cap.holdout.size(), tables[k].size());
    const Capture read = read_manifest(cap_dir);
    ASSERT_EQ(read.holdout.size(), cap.holdout.size());
    EXPECT_EQ(read.holdout.back().u1, cap.holdout.back().u1);
    PipelineOptions po;
    const Calibration c = calibrate_capture(read, cap_dir, po);
    const std::vector<HoldoutReport> r = recover_holdout(read, cap_dir, c, po);
    ASSERT_EQ(r.size(), cap.holdout.size());
    for (const HoldoutReport& h : r) {
      EXPECT_GT(h.pixels, 3u) << h.name;
      EXPECT_EQ(h.rejected, 0u) << h.name;
      EXPECT_LT(h.rms, 0.004) << h.name;
      EXPECT_LT((h.recovered - h.truth).cwiseAbs().maxCoeff(), 0.01) << h.name;
    }
  }
}

TEST(Holdout, FilterCaptureRecoversAPatchInTheBasisSpan) {
  // Six broad filters, a 4-d basis, patches tabulated on the bands (the simulator's spectrum is then the model's,
  // linear between bands): inside the span the recovery is exact but for calibration and quantisation; a narrow
  // bump outside it is not.
  test::ScratchDir dir;
  const std::vector<double> bands = bands_420_720();
  Eigen::MatrixXd basis(Eigen::Index(bands.size()), 4);
  for (Eigen::Index b = 0; b < basis.rows(); ++b) {
    const double x = (bands[std::size_t(b)] - 570) / 150;
    basis.row(b) << 1, x, x * x, std::sin(3 * x);
  }
  const Eigen::Vector4d inside(0.4, -0.1, 0.2, 0.05);
  auto spectrum = [&](std::size_t i, double l) {
    const auto b = Eigen::Index(std::lround((l - 420) / 10));
    return i == 0 ? basis.row(b).dot(inside) : 0.1 + 0.6 * std::exp(-0.5 * std::pow((l - 520) / 12, 2));
  };
  FilterSet f;
  f.nm = every(400, 740, 2);
  for (int j = 0; j < 6; ++j) {
    f.names.push_back("g" + std::to_string(j));
    for (const double l : f.nm)
      f.transmission.resize(std::size_t(j) + 1),
          f.transmission[std::size_t(j)].push_back(0.9 * std::exp(-0.5 * std::pow((l - (445 + 50.0 * j)) / 35, 2)));
  }
  SimulatorOptions o = test::small_rig(80, 50, 3, 30, bands, false);
  o.filters = f;
  o.holdout = table(2, bands, spectrum);
  simulate_capture(o, dir / "cap");
  const Capture cap = read_manifest(dir / "cap");
  PipelineOptions po;
  po.fit_targets = {"red", "green", "blue", "yellow", "white"};
  po.filter_terms = 3;
  po.filter_basis = basis;
  po.filter_ridge = 0;
  const Calibration c = calibrate_capture(cap, dir / "cap", po);
  const std::vector<HoldoutReport> r = recover_holdout(cap, dir / "cap", c, po);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_LT(r[0].rms, 0.004) << "inside the span";
  EXPECT_GT(r[1].rms, 0.03) << "a 12 nm bump outside the span";
}

TEST(Holdout, AFiltersClampedExposuresDoNotShiftTheSceneBetweenLights) {
  // Filter 'dim' comes first and takes fewer exposures per light (its bracket runs past 60 s); the open filter's scene
  // images after it must be those of a capture without it, light by light and exposure by exposure.
  test::ScratchDir dir;
  FilterSet one;
  one.nm = {400, 500, 600, 740};
  one.names = {"open"};
  one.transmission = {{0.9, 0.9, 0.9, 0.9}};
  FilterSet two = one;
  two.names.insert(two.names.begin(), "dim");
  two.transmission.insert(two.transmission.begin(), {0.001, 0.001, 0.001, 0.001});
  SimulatorOptions o = test::small_rig(48, 24, 3, 30, bands_420_720(), false);
  o.filters = two;
  const Capture both = simulate_capture(o, dir / "two");
  o.filters = one;
  const Capture alone = simulate_capture(o, dir / "one");
  std::size_t compared = 0, dim = 0;
  for (const CaptureImage& im : both.images) {
    if (im.kind != ImageKind::scene) continue;
    if (im.band == 0) {
      ++dim;
      continue;
    }
    for (const CaptureImage& same : alone.images)
      if (same.kind == ImageKind::scene && same.light == im.light && same.exposure_s == im.exposure_s) {
        EXPECT_EQ(test::read_bytes(dir / "two" / im.file), test::read_bytes(dir / "one" / same.file)) << im.file;
        ++compared;
      }
  }
  EXPECT_EQ(compared, 3u * 11u);
  EXPECT_LT(dim, 3u * 11u);
}
