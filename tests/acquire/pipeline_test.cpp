// The acquisition pipeline on simulated captures with known truth: noise-free samples within 1 % (median
// relative) of the analytic BRDF at their angles, noisy samples unbiased, the calibration stored and read back
// unchanged, and broken captures refused with one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "small_rig.h"
#include "specula/acquire/pipeline.h"
#include "specula/acquire/simulate.h"
#include "specula/core/brdf_materials.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;

namespace {

SimulatorOptions rig(bool noise) {
  SimulatorOptions o = test::small_rig(128, 90, 6, 25, {450, 550, 650}, noise);
  o.passband = Passband::delta;
  return o;
}

// Ratios sample / model over every band of every sample (model values above 1e-3 of the largest).
std::vector<double> ratios(const std::filesystem::path& store, const std::string& material) {
  const store::Store s = store::Store::open(store);
  const store::SamplesInfo info = s.samples_info("scan");
  std::vector<double> angles(4 * info.size);
  std::vector<float> values(info.size * info.bands);
  s.read_samples("scan", 0, info.size, angles, values);
  const auto model = brdf::make_material(material, info.wavelengths);
  std::vector<double> f(info.bands), r;
  for (std::size_t i = 0; i < info.size; ++i) {
    model->eval(brdf::StdAngles{angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]}, f);
    for (std::size_t b = 0; b < info.bands; ++b)
      if (f[b] > 1e-3) r.push_back(values[i * info.bands + b] / f[b]);
  }
  return r;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return v[v.size() / 2];
}

ExtractResult run(const SimulatorOptions& o, const std::filesystem::path& dir, Calibration* out = nullptr) {
  const Capture cap = simulate_capture(o, dir / "cap");
  const Capture back = read_manifest(dir / "cap");
  const Calibration c = calibrate_capture(back, dir / "cap", {});
  store::StoreWriter w(dir / "s.h5", {});
  write_calibration(w, "scan", c);
  const ExtractResult r = extract_samples(back, dir / "cap", c, {}, w, "scan");
  w.commit();
  if (out) *out = c;
  return r;
}

TEST(Pipeline, NoiseFreeSamplesMatchTheAnalyticBrdf) {
  test::ScratchDir dir;
  const ExtractResult r = run(rig(false), dir.path());
  EXPECT_GT(r.samples, 10000u);
  EXPECT_GT(r.rejected[std::size_t(Reject::shadowed)], 0u);
  std::vector<double> err;
  for (const double x : ratios(dir / "s.h5", "red-plastic")) err.push_back(std::abs(x - 1));
  ASSERT_GT(err.size(), 30000u);
  EXPECT_LT(median(err), 0.01);
}

TEST(Pipeline, NoisySamplesAreUnbiased) {
  test::ScratchDir dir;
  run(rig(true), dir.path());
  const std::vector<double> r = ratios(dir / "s.h5", "red-plastic");
  ASSERT_GT(r.size(), 30000u);
  EXPECT_NEAR(median(r), 1.0, 0.01);
}

TEST(Pipeline, CalibrationIsStoredAndReadBackUnchanged) {
  test::ScratchDir dir;
  Calibration c;
  run(rig(false), dir.path(), &c);
  const Calibration back = read_calibration(store::Store::open(dir / "s.h5"), "scan");
  EXPECT_EQ(back.spatial.value, c.spatial.value);
  EXPECT_EQ(back.spectral.recovery, c.spectral.recovery);
  EXPECT_EQ(back.sphere.centre, c.sphere.centre);
  EXPECT_EQ(back.circle.r, c.circle.r);
  ASSERT_EQ(back.light_dirs.size(), c.light_dirs.size());
  for (std::size_t l = 0; l < c.light_dirs.size(); ++l) EXPECT_EQ(back.light_dirs[l], c.light_dirs[l]);
  EXPECT_THROW(read_calibration(store::Store::open(dir / "s.h5"), "other"), InputError);
}

TEST(Pipeline, BrokenCapturesAreRefusedWithOneLine) {
  test::ScratchDir dir;
  simulate_capture(rig(false), dir / "sat");
  const Capture sat = read_manifest(dir / "sat");
  // Every exposure of light 1 at 550 nm saturated, as a capture with too long exposures would be.
  const std::vector<std::uint16_t> white(128 * 128, 4095);
  for (const auto& im : sat.images)
    if (im.kind == ImageKind::scene && im.light == 1 && im.band == 1)
      store::write_png_gray16(dir / "sat" / im.file, 128, 128, white);
  const Calibration c = calibrate_capture(sat, dir / "sat", {});
  store::StoreWriter w(dir / "x.h5", {});
  try {
    extract_samples(sat, dir / "sat", c, {}, w, "scan");
    ADD_FAILURE() << "an all-saturated capture was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("light 1 at 550 nm is saturated on the whole sphere"), std::string::npos)
        << e.what();
  }
  // A silhouette without a sphere.
  simulate_capture(rig(false), dir / "cap");
  const std::vector<std::uint16_t> board(128 * 128, 3000);
  store::write_png_gray16(dir / "cap" / "silhouette.png", 128, 128, board);
  try {
    calibrate_capture(read_manifest(dir / "cap"), dir / "cap", {});
    ADD_FAILURE() << "a silhouette without a sphere was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("silhouette.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no dark sphere"), std::string::npos) << e.what();
  }
}

TEST(Pipeline, RunPrintsTheIssuesJsonKeys) {
  test::ScratchDir dir;
  ASSERT_EQ(test::run_specula(
                "simulate-capture --size 128x128 --sphere-px 90 --lights 5 --light-step 25 --bands 500,600 -o '" +
                (dir / "cap").string() + "'")
                .status,
            0);
  const auto r =
      test::run_specula("acquire run '" + (dir / "cap").string() + "' -o '" + (dir / "s.h5").string() + ":red' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* key : {"\"samples\"", "\"rejected\"", "\"shadowed\"", "\"saturated\"", "\"bloom\"", "\"low_signal\"",
                          "\"sphere\"", "\"circle\"", "\"light_dir_error_deg\"", "\"seconds\""})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " not in " << r.output;
  EXPECT_LT(test::json_number(r.output, "light_dir_error_max_deg"), 0.25);
  EXPECT_GT(test::json_number(r.output, "samples"), 1000);
  const store::Store s = store::Store::open(dir / "s.h5");
  EXPECT_EQ(s.samples(), std::vector<std::string>{"red"});
  // A second run without --replace refuses and leaves the store as it was.
  const std::string before = test::read_bytes(dir / "s.h5");
  const auto again =
      test::run_specula("acquire run '" + (dir / "cap").string() + "' -o '" + (dir / "s.h5").string() + ":red'");
  EXPECT_EQ(again.status, 1) << again.output;
  EXPECT_EQ(test::read_bytes(dir / "s.h5"), before);
}

}  // namespace

namespace {

// A spectral grid as the sphere's material: the pipeline recovers the grid's values at the samples' angles.
TEST(Pipeline, GridMaterialIsRecovered) {
  test::ScratchDir dir;
  const std::string store = (dir / "m.h5").string();
  ASSERT_EQ(test::run_specula("synth-brdf green-matte -o '" + store + ":g'").status, 0);
  const auto sim = test::run_specula("simulate-capture --material '" + store +
                                     ":g' --size 128x128 --sphere-px 90 --lights 5 "
                                     "--light-step 25 --bands 450,550,650 --passband delta --no-noise -o '" +
                                     (dir / "cap").string() + "'");
  ASSERT_EQ(sim.status, 0) << sim.output;
  const auto r =
      test::run_specula("acquire run '" + (dir / "cap").string() + "' -o '" + (dir / "s.h5").string() + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LT(test::json_number(r.output, "truth_median_rel_error"), 0.01) << r.output;
  EXPECT_NEAR(test::json_number(r.output, "truth_median_ratio"), 1.0, 0.01) << r.output;
}

}  // namespace

namespace {

// A filter capture of two lights in `dir` whose scene images through filter k are uniform at values[k][e], taken at
// times[k][e]; the manifest written.
Capture uniform_filter_capture(const std::filesystem::path& dir, const std::vector<std::vector<double>>& times,
                               const std::vector<std::vector<std::uint16_t>>& values) {
  Capture c;
  c.width = c.height = 4;
  c.focal_px = 100;
  c.bands = {450, 550, 650};
  c.light_angles_deg = {20, 40};
  c.light_spectrum_nm = {400, 700};
  c.light_spectrum = {1, 1};
  FilterSet f;
  f.nm = {400, 700};
  for (std::size_t k = 0; k < times.size(); ++k)
    f.names.push_back("F" + std::to_string(k)), f.transmission.push_back({1, 1});
  c.filters = f;
  std::filesystem::create_directories(dir);
  for (int l = 0; l < 2; ++l)
    for (std::size_t k = 0; k < times.size(); ++k)
      for (std::size_t e = 0; e < times[k].size(); ++e) {
        const std::string file = "L" + std::to_string(l) + "-F" + std::to_string(k) + "-" + std::to_string(e) + ".png";
        store::write_png_gray16(dir / file, 4, 4, std::vector<std::uint16_t>(16, values[k][e]));
        c.images.push_back({file, ImageKind::scene, l, int(k), -1, times[k][e]});
      }
  return c;
}

// Relative noise of a merged rate in closed form: sqrt(variance) / rate.
double relative(double rate, double variance) { return std::sqrt(variance) / rate; }

}  // namespace

TEST(FilterReadingNoise, FollowsEachFiltersRecordedExposuresAndLevels) {
  test::ScratchDir dir;
  const SensorNoise shot{.read_noise_dn = 0}, n;
  // Filter 1 exposed 4 times longer at the same light (808 and 3208 DN with the bias of 8: one value each, merged
  // as value over time): shot-noise-limited relative variances in the ratio 4 (the rounding and the bias aside),
  // i.e. the Wiener solve's weights 1/sigma^2 in the ratio 1:4.
  Capture c = uniform_filter_capture(dir / "a", {{1}, {4}}, {{808}, {3208}});
  Eigen::VectorXd rel = filter_reading_noise(c, dir / "a", shot, {});
  const double r0 = 808, r1 = 3208 / 4.0;
  EXPECT_DOUBLE_EQ(rel[0], relative(r0, r0 / 4 + 1.0 / 12));
  EXPECT_DOUBLE_EQ(rel[1], relative(r1, (r1 * 4 / 4 + 1.0 / 12) / 16));
  EXPECT_NEAR(std::pow(rel[0] / rel[1], 2), 4, 0.05);
  // A dim filter at the 60 s cap read once at 300 DN against a bright one bracketed to 3 values on a line
  // (rate 1000 DN/s): the dim one's value over 60 s has sqrt(read^2 + shot + 1/12) / 60 of noise.
  c = uniform_filter_capture(dir / "b", {{20, 60}, {0.1, 0.3, 1, 3}}, {{100, 300}, {108, 308, 1008, 3008}});
  rel = filter_reading_noise(c, dir / "b", n, {});
  EXPECT_DOUBLE_EQ(rel[0], relative(5, (2.25 + 300 / 4.0 + 1.0 / 12) / 3600));
  EXPECT_NEAR(rel[1], relative(1000, hdr_rate_variance(1000, std::vector<double>{0.1, 0.3, 1, 3}, 12, n)), 1e-12);
  EXPECT_GT(rel[0], 2 * rel[1]);
  // No pixel read in every filter (the dim one below the linear range): refused, naming the capture.
  c = uniform_filter_capture(dir / "c", {{60}, {1}}, {{188}, {1008}});
  try {
    filter_reading_noise(c, dir / "c", n, {});
    ADD_FAILURE() << "no pixel qualifies";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no scene pixel is read in every filter"), std::string::npos) << e.what();
  }
}

TEST(PixelReadings, ADarkChannelIsReadAtItsLongestExposureLessTheBias) {
  // Exact lines of value = 8 (SensorNoise's bias) + rate t on a 12-bit sensor, range 241-3854: channel 0 at 400 DN/s
  // is in range; channel 1 at 20 DN/s stays below it (168 DN at 8 s), so its rate is (168 - 8) / 8 = 20.
  const std::vector<double> times = {1, 2, 4, 8};
  auto channel = [&](std::vector<double> rates) {
    std::vector<std::vector<std::uint16_t>> images(times.size(), std::vector<std::uint16_t>(rates.size()));
    for (std::size_t e = 0; e < times.size(); ++e)
      for (std::size_t p = 0; p < rates.size(); ++p)
        images[e][p] = std::uint16_t(std::min(4095.0, std::round(8 + rates[p] * times[e])));
    std::vector<std::span<const std::uint16_t>> views(images.begin(), images.end());
    return merge_exposures(views, times, 12, {});
  };
  // Pixel 0: one channel lit, one dark; pixel 1: both dark; pixel 2: channel 0 saturated, channel 1 dark.
  const std::vector<HdrImage> hdr = {channel({400, 20, 1e6}), channel({20, 12, 20})};
  ASSERT_EQ(hdr[1].status[0], HdrStatus::low_signal);
  const GreyImage flat{.width = 3, .height = 1, .value = {0.5f, 0.5f, 0.5f}};
  Eigen::VectorXd h;
  const PipelineOptions keep;
  EXPECT_EQ(pixel_readings(hdr, 0, flat, keep, h), Reject::count);
  EXPECT_NEAR(h[0], 400 / 0.5, 1e-3);
  EXPECT_NEAR(h[1], 20 / 0.5, 1e-3);
  EXPECT_EQ(pixel_readings(hdr, 1, flat, keep, h), Reject::low_signal);
  EXPECT_EQ(pixel_readings(hdr, 2, flat, keep, h), Reject::saturated);
  PipelineOptions reference;
  reference.keep_dark_channels = false;
  EXPECT_EQ(pixel_readings(hdr, 0, flat, reference, h), Reject::low_signal);
  EXPECT_EQ(pixel_readings(hdr, 2, flat, reference, h), Reject::saturated);
}
