// `specula filters design`, `simulate-capture --filters` and `acquire run` on a filter capture end to end: curves
// written as transmissions with the held-out error, bad filter files refused with one line naming the file and
// nothing written, a filter capture reconstructed through its basis, and version-1 captures still read.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <regex>
#include <set>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "specula/acquire/capture.h"
#include "specula/acquire/filters.h"
#include "test_support.h"

using namespace specula;
using test::json_number;
using test::run_specula;

namespace {

// 60 smooth reflectances on 420-720 nm every 10 nm (a header of wavelengths, one spectrum a row).
std::string smooth_spectra_csv() {
  std::string csv = "name";
  for (int l = 420; l <= 720; l += 10) csv += fmt::format(",{}", l);
  csv += "\n";
  for (int i = 0; i < 60; ++i) {
    csv += fmt::format("s{}", i);
    const double c = 430 + 5.0 * i, w = 40 + (i % 7) * 15, base = 0.05 + 0.01 * (i % 9);
    for (int l = 420; l <= 720; l += 10)
      csv += fmt::format(",{:.5f}", base + 0.6 * std::exp(-0.5 * std::pow((l - c) / w, 2)));
    csv += "\n";
  }
  return csv;
}

const std::string kRig = "--size 80x80 --sphere-px 50 --lights 3 --light-step 30 ";

TEST(FiltersCli, DesignSimulateAndReconstruct) {
  test::ScratchDir dir;
  const auto db = (dir / "db.h5").string(), filters = (dir / "f.csv").string(), cap = (dir / "cap").string(),
             out = (dir / "s.h5").string();
  test::write_file(dir / "spectra.csv", smooth_spectra_csv());
  ASSERT_EQ(run_specula("-q import '" + (dir / "spectra.csv").string() + "' --name spectra -o '" + db + "'").status, 0);
  ASSERT_EQ(run_specula("-q pca '" + db + "' --collection spectra --name pca").status, 0);
  auto r = run_specula("filters design '" + db + "' --basis pca -k 4 -o '" + filters + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "filters"), 4);
  EXPECT_NE(r.output.find("\"spectra\":\"spectra (every fifth spectrum)\""), std::string::npos) << r.output;
  const acquire::FilterSet f = acquire::read_filters_csv(filters);
  ASSERT_EQ(f.size(), 4u);
  for (const auto& t : f.transmission)
    for (const double v : t) EXPECT_TRUE(v >= 0 && v <= 0.9 + 1e-6);

  r = run_specula("simulate-capture " + kRig + "--filters '" + filters + "' -o '" + cap + "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "channels"), 4);
  EXPECT_EQ(json_number(r.output, "scene_images"), 3 * 4 * 11);
  EXPECT_NE(test::read_bytes(std::filesystem::path(cap) / "manifest.json").find("\"version\": 3"), std::string::npos);
  r = run_specula("acquire run '" + cap + "' -o '" + out + ":scan' --basis '" + db +
                  ":pca' --fit-targets red,green,blue,yellow,white --filter-terms 3 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_GT(json_number(r.output, "samples"), 1000);
  // The targets' reflectance from 4 readings on a 4-d basis of toy spectra (targets not among them): coarse.
  const std::string s = r.output;
  const std::regex rms("\"rms_filters\":([0-9.e-]+)");
  int targets = 0;
  for (auto it = std::sregex_iterator(s.begin(), s.end(), rms); it != std::sregex_iterator(); ++it, ++targets)
    EXPECT_LT(std::stod((*it)[1]), 0.15) << r.output;
  EXPECT_EQ(targets, 5);
  EXPECT_LT(json_number(r.output, "truth_median_rel_error"), 0.25) << r.output;
  const double samples = json_number(r.output, "samples"), truth = json_number(r.output, "truth_median_rel_error");

  // The stored filter calibration is reused by acquire samples: the same samples without the basis or targets.
  r = run_specula("acquire samples '" + cap + "' -o '" + out + ":again' --calibration scan --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_number(r.output, "samples"), samples) << r.output;
  EXPECT_EQ(json_number(r.output, "truth_median_rel_error"), truth) << r.output;
  // The ridge solve is the other choice; the Wiener solve needs a basis that stores a second moment.
  r = run_specula("acquire run '" + cap + "' -o '" + out + ":ridge' --basis '" + db +
                  ":pca' --filter-solve ridge --fit-targets red,green,blue,yellow,white --filter-terms 3 --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LT(json_number(r.output, "truth_median_rel_error"), 0.25) << r.output;
  // acquire hdr refuses a filter capture with one line saying why, and writes nothing.
  const auto hdr_store = (dir / "hdr.h5").string();
  r = run_specula("acquire hdr '" + cap + "' -o '" + hdr_store + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("4 channels are filters, not wavelength bands"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(hdr_store));

  // A basis on other bands than the capture's is refused with one line.
  ASSERT_EQ(run_specula("-q import '" + (dir / "spectra.csv").string() +
                        "' --wavelengths 450:700:10 --name narrow -o '" + db + "'")
                .status,
            0);
  ASSERT_EQ(run_specula("-q pca '" + db + "' --collection narrow --name narrow").status, 0);
  r = run_specula("acquire run '" + cap + "' -o '" + out + ":x' --basis '" + db + ":narrow'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("learn the basis on the capture's bands"), std::string::npos) << r.output;
}

TEST(FiltersCli, BadFilterFilesAreRefusedWithOneLineAndNothingWritten) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string();
  test::write_file(dir / "neg.csv", "wavelength_nm,a,b\n400,0.5,0.1\n560,0.5,-0.2\n740,0.5,0.1\n");
  auto r = run_specula("simulate-capture " + kRig + "--filters '" + (dir / "neg.csv").string() + "' -o '" + cap + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("neg.csv:3: filter 'b' transmits -0.2"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  test::write_file(dir / "short.csv", "wavelength_nm,a\n450,0.5\n700,0.5\n");
  r = run_specula("simulate-capture " + kRig + "--filters '" + (dir / "short.csv").string() + "' -o '" + cap + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("short.csv: the filters are tabulated over 450-700 nm; the bands need 420-720 nm"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(cap));
  EXPECT_FALSE(std::filesystem::exists(cap + ".partial"));
}

TEST(FiltersCli, ADimFilterTakesTheLongestExposureOnce) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string();
  // Filter 'dim' passes 1/900 of 'open': its 11-exposure bracket, scaled by its gain, runs past the 60 s cap.
  test::write_file(dir / "dim.csv",
                   "wavelength_nm,open,dim\n400,0.9,0.001\n500,0.9,0.001\n600,0.9,0.001\n740,0.9,0.001\n");
  const auto r = run_specula("simulate-capture " + kRig + "--filters '" + (dir / "dim.csv").string() + "' -o '" + cap +
                             "' --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const acquire::Capture c = acquire::read_manifest(cap);  // refuses two images of one light, channel and time
  std::vector<double> open, dim;
  for (const auto& im : c.images)
    if (im.kind == acquire::ImageKind::scene && im.light == 0) (im.band == 0 ? open : dim).push_back(im.exposure_s);
  EXPECT_EQ(open.size(), 11u);
  ASSERT_FALSE(dim.empty());
  EXPECT_LT(dim.size(), 11u);
  EXPECT_EQ(*std::max_element(dim.begin(), dim.end()), 60.0);
  EXPECT_EQ(std::set<double>(dim.begin(), dim.end()).size(), dim.size());
}

TEST(FiltersCli, VersionOneCapturesStillRead) {
  test::ScratchDir dir;
  const auto cap = (dir / "cap").string();
  ASSERT_EQ(run_specula("simulate-capture --size 80x80 --sphere-px 50 --lights 2 --light-step 50 --bands 500,600 "
                        "--exposures 0.01,0.1,1 --no-noise -o '" +
                        cap + "'")
                .status,
            0);
  const auto manifest = std::filesystem::path(cap) / "manifest.json";
  std::string text = test::read_bytes(manifest);
  const auto at = text.find("\"version\": 3");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 12, "\"version\": 1");
  test::write_file(manifest, text);
  const auto r = run_specula("acquire hdr '" + cap + "' -o '" + (dir / "s.h5").string() + "' --json");
  EXPECT_EQ(r.status, 0) << r.output;
  // Filters need version 2.
  const auto bands = text.find("\"bands_nm\"");
  text.insert(bands, "\"filters\": {\"names\": [\"a\"], \"nm\": [400, 740], \"transmission\": [[1, 1]]},\n ");
  test::write_file(manifest, text);
  const auto v1 = run_specula("acquire hdr '" + cap + "' -o '" + (dir / "t.h5").string() + "'");
  EXPECT_EQ(v1.status, 1);
  EXPECT_NE(v1.output.find("\"filters\" needs capture format version 2"), std::string::npos) << v1.output;
}

}  // namespace

namespace {

// The numbers of the JSON array "key":[...] in `json`.
std::vector<double> json_array(const std::string& json, const std::string& key) {
  std::vector<double> out;
  const auto at = json.find("\"" + key + "\":[");
  if (at == std::string::npos) return out;
  std::stringstream s(json.substr(at + key.size() + 4, json.find(']', at) - at - key.size() - 4));
  for (std::string cell; std::getline(s, cell, ',');) out.push_back(std::stod(cell));
  return out;
}

}  // namespace

TEST(FiltersCli, TheSolvesNoiseFollowsTheExposuresTheCaptureRecorded) {
  test::ScratchDir dir;
  const auto db = (dir / "db.h5").string(), cap = (dir / "cap").string(), out = (dir / "s.h5").string();
  test::write_file(dir / "spectra.csv", smooth_spectra_csv());
  ASSERT_EQ(run_specula("-q import '" + (dir / "spectra.csv").string() + "' --name spectra -o '" + db + "'").status, 0);
  ASSERT_EQ(run_specula("-q pca '" + db + "' --collection spectra --name pca").status, 0);
  test::write_file(dir / "f.csv",
                   "wavelength_nm,blue,green,red\n400,0.9,0.1,0\n500,0.5,0.8,0.1\n600,0.1,0.6,0.7\n"
                   "740,0,0.1,0.9\n");
  auto r = run_specula("simulate-capture " + kRig + "--filters '" + (dir / "f.csv").string() + "' -o '" + cap + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string run = "acquire run '" + cap + "' --basis '" + db + ":pca' --json --no-suite -o '" + out;
  r = run_specula(run + ":full'");
  ASSERT_EQ(r.status, 0) << r.output;
  // Every filter bracketed to fill the sensor: noise levels within 25 % of the typical 0.002.
  const std::vector<double> full = json_array(r.output, "filter_noise");
  ASSERT_EQ(full.size(), 3u) << r.output;
  for (const double v : full) EXPECT_NEAR(v, 0.002, 0.0005) << r.output;

  // The capture as a rig that took one exposure through 'blue' per light (its third longest): its readings are then
  // one value each, whose noise differs from a bracket's line (lower near full scale, higher near the range's
  // floor), and the solve's noise for 'blue' follows; the other filters' images are unchanged.
  acquire::Capture c = acquire::read_manifest(cap);
  std::vector<acquire::CaptureImage> kept;
  for (const auto& im : c.images) {
    if (im.kind != acquire::ImageKind::scene || im.band != 0) {
      kept.push_back(im);
      continue;
    }
    double third = 0;
    std::vector<double> t;
    for (const auto& x : c.images)
      if (x.kind == im.kind && x.band == 0 && x.light == im.light) t.push_back(x.exposure_s);
    std::sort(t.begin(), t.end());
    third = t[t.size() - 3];
    if (im.exposure_s == third) kept.push_back(im);
  }
  c.images = kept;
  acquire::write_manifest(cap, c);
  r = run_specula(run + ":one'");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<double> noise = json_array(r.output, "filter_noise");
  ASSERT_EQ(noise.size(), 3u) << r.output;
  EXPECT_GT(std::abs(noise[0] / full[0] - 1), 0.1) << r.output;
  // --equal-filter-noise: the former model, every filter the same.
  r = run_specula(run + ":equal' --equal-filter-noise --filter-noise 0.003");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(json_array(r.output, "filter_noise"), std::vector<double>(3, 0.003)) << r.output;
}
