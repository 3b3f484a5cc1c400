// The capture simulator: its silhouette is the ray-traced sphere of the truth it records, its files do not depend
// on the thread count, a noise-free capture merges into clean lines on the sphere, and the manifest reader
// refuses broken captures with one line naming the problem.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>

#include "small_rig.h"
#include "specula/acquire/capture.h"
#include "specula/acquire/hdr.h"
#include "specula/acquire/simulate.h"
#include "specula/store/io/png_stack.h"
#include "test_support.h"

using namespace specula;
using namespace specula::acquire;

namespace {

SimulatorOptions small(bool noise) {
  SimulatorOptions o = test::small_rig(96, 60, 3, 40, {450, 550, 650}, noise);
  o.exposures_s = {1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1, 3};
  return o;
}

TEST(Simulator, SilhouetteIsTheRayTracedSphereOfItsTruth) {
  test::ScratchDir dir;
  const Capture c = simulate_capture(small(false), dir / "cap");
  ASSERT_TRUE(c.truth.has_value());
  const Eigen::Vector3d centre(c.truth->sphere_centre[0], c.truth->sphere_centre[1], c.truth->sphere_centre[2]);
  const double r = c.truth->sphere_radius;
  const store::PngImage s = store::read_png(dir / "cap" / "silhouette.png");
  ASSERT_EQ(s.width, 96u);
  std::size_t disagree = 0, inside = 0;
  for (int v = 0; v < 96; ++v)
    for (int u = 0; u < 96; ++u) {
      const Eigen::Vector3d d =
          Eigen::Vector3d((u + 0.5 - c.cx) / c.focal_px, (v + 0.5 - c.cy) / c.focal_px, 1).normalized();
      const double b = d.dot(centre), disc = b * b - centre.squaredNorm() + r * r;
      // Centre-of-pixel test against the image: dark (sphere) or bright (board); edge pixels are mixed.
      const bool hit = disc > 0;
      const double value = s.samples[std::size_t(v * 96 + u)];
      inside += hit;
      if ((hit && value > 2500) || (!hit && value < 500)) ++disagree;
    }
  EXPECT_NEAR(double(inside), 3.14159 * 30 * 30, 0.05 * 3.14159 * 30 * 30);
  EXPECT_EQ(disagree, 0u);
}

TEST(Simulator, FilesDoNotDependOnTheThreadCount) {
  test::ScratchDir dir;
  const std::string args =
      "simulate-capture --size 64x64 --sphere-px 40 --lights 2 --bands 500,600 --exposures 0.01,0.1 ";
  const auto one =
      test::run_shell("OMP_NUM_THREADS=1 '" SPECULA_BINARY "' " + args + "-o '" + (dir / "a").string() + "'");
  const auto two =
      test::run_shell("OMP_NUM_THREADS=2 '" SPECULA_BINARY "' " + args + "-o '" + (dir / "b").string() + "'");
  ASSERT_EQ(one.status, 0) << one.output;
  ASSERT_EQ(two.status, 0) << two.output;
  const auto diff = test::run_shell("diff -r '" + (dir / "a").string() + "' '" + (dir / "b").string() + "'");
  EXPECT_EQ(diff.status, 0) << diff.output;
}

TEST(Simulator, NoiseFreeCaptureMergesIntoCleanLinesOnTheSphere) {
  test::ScratchDir dir;
  const Capture c = simulate_capture(small(false), dir / "cap");
  const Capture back = read_manifest(dir / "cap");
  EXPECT_EQ(back.images.size(), c.images.size());
  EXPECT_EQ(back.bands, c.bands);
  // Light 1, band 550: merge its exposure series.
  std::vector<std::vector<std::uint16_t>> px;
  std::vector<double> times;
  for (const auto& im : back.images)
    if (im.kind == ImageKind::scene && im.light == 1 && im.band == 1) {
      px.push_back(store::read_png(dir / "cap" / im.file).samples);
      times.push_back(im.exposure_s);
    }
  ASSERT_EQ(times.size(), 8u);
  std::vector<std::span<const std::uint16_t>> views(px.begin(), px.end());
  const HdrImage h = merge_exposures(views, times, 12);
  std::size_t fitted = 0;
  for (std::size_t p = 0; p < h.pixels; ++p) {
    if (h.status[p] != HdrStatus::ok) continue;
    ++fitted;
    EXPECT_GT(h.pearson[p], 0.9999) << p;
    // Quantisation only: value - rate t - bias stays within half a count plus the fit's slack.
    for (std::size_t e = 0; e < times.size(); ++e) {
      const double v = px[e][p];
      if (v >= 241 && v <= 3854) {
        EXPECT_NEAR(v, 8 + h.rate[p] * times[e], 3.0) << p << " " << e;
      }
    }
  }
  EXPECT_GT(fitted, 800u);  // most of the lit half of a 60-pixel sphere
}

TEST(Simulator, BadCapturesAreRefusedWithOneLine) {
  test::ScratchDir dir;
  simulate_capture(small(true), dir / "cap");
  const auto manifest = dir / "cap" / "manifest.json";
  const std::string good = test::read_bytes(manifest);
  auto refuse = [&](const std::string& text, const std::string& expect) {
    std::ofstream(manifest) << text;
    try {
      read_manifest(dir / "cap");
      ADD_FAILURE() << "accepted: " << expect;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  };
  refuse("{ not json", "not valid JSON");
  refuse(std::regex_replace(good, std::regex("specula-capture"), "other"), "not a specula capture manifest");
  refuse(std::regex_replace(good, std::regex("\"version\": 3"), "\"version\": 9"), "version 9");
  refuse(std::regex_replace(good, std::regex("\"band\": 2"), "\"band\": 7", std::regex_constants::format_first_only),
         "band 7");
  refuse(std::regex_replace(good, std::regex("scene/L000/B450-1ms.png"), "../escape.png"),
         "inside the capture directory");
  std::ofstream(manifest) << good;
  std::filesystem::remove(dir / "cap" / "scene" / "L001" / "B550-10ms.png");
  refuse(good, "file is missing");
  // With every exposure of one light and band gone from the manifest, that pair has no data.
  // (Plain string search: std::regex recurses once per character and overflows the stack on long manifests.)
  std::string without = good;
  for (std::size_t at; (at = without.find("\"file\": \"scene/L002/B650-")) != std::string::npos;) {
    const std::size_t open = without.rfind('{', at), close = without.find('}', at);
    ASSERT_NE(open, std::string::npos);
    ASSERT_NE(close, std::string::npos);
    without.erase(open, close + 1 - open + (close + 1 < without.size() && without[close + 1] == ',' ? 1 : 0));
  }
  std::filesystem::copy_file(dir / "cap" / "scene" / "L001" / "B550-1ms.png",
                             dir / "cap" / "scene" / "L001" / "B550-10ms.png");
  refuse(std::regex_replace(without, std::regex(R"(,\s*\])"), "]"), "no scene exposure for light 2 at 650 nm");
}

}  // namespace
