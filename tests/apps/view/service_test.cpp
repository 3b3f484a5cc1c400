// The viewer's API (apps/view/service.h) on a store whose every value is known: spectra as written, PCA
// reconstruction in closed form, NMF reconstruction against brute-force NNLS, grid and sample slices from their
// construction, pictures decoded back; every malformed request gets a 4xx and one line.
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <numbers>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "apps/view/service.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/colour.h"
#include "specula/core/nnls.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using std::numbers::pi;

namespace {

constexpr std::size_t kW = 6, kH = 4, kB = 31;

float value(std::size_t x, std::size_t y, std::size_t b) { return float(0.1 + 0.02 * x + 0.005 * y + 0.003 * b); }

// The numbers of JSON array `key` (the first one after "key":), nulls as NaN.
std::vector<double> json_array_of(const std::string& json, const std::string& key, std::size_t skip = 0) {
  std::size_t at = json.find("\"" + key + "\":[");
  for (std::size_t i = 0; i < skip && at != std::string::npos; ++i) at = json.find("\"" + key + "\":[", at + 1);
  if (at == std::string::npos) return {};
  at = json.find('[', at) + 1;
  std::vector<double> v;
  while (at < json.size() && json[at] != ']') {
    const std::size_t end = json.find_first_of(",]", at);
    const std::string item = json.substr(at, end - at);
    v.push_back(item == "null" ? std::nan("") : std::stod(item));
    at = json[end] == ',' ? end + 1 : end;
  }
  return v;
}

class ViewService : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::ScratchDir();
    path_ = dir_->path() / "view.h5";
    const WavelengthGrid wl = WavelengthGrid::range(420, 720, 10);
    store::StoreWriter w(path_, {});
    store::Cube c;
    c.resize(kH, kW, kB);
    c.wavelengths = wl;
    c.units = "reflectance";
    c.mask.assign(kH * kW, 1);
    for (std::size_t y = 0; y < kH; ++y)
      for (std::size_t x = 0; x < kW; ++x)
        for (std::size_t b = 0; b < kB; ++b) c.pixel(y, x)[b] = value(x, y, b);
    c.mask[3 * kW + 5] = 0;
    w.add_image("img", c);

    Eigen::MatrixXd random(kB, 3);
    for (Eigen::Index b = 0; b < Eigen::Index(kB); ++b)
      for (Eigen::Index j = 0; j < 3; ++j) random(b, j) = std::cos(0.29 * double(b + 1) * double(j + 2) + double(j));
    const Eigen::MatrixXd q =
        Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ() * Eigen::MatrixXd::Identity(kB, 3);
    store::Basis pca;
    pca.method = "pca";
    pca.wavelengths = wl;
    pca.n = 24;
    pca.mean = Eigen::VectorXd::LinSpaced(Eigen::Index(kB), 0.2, 0.3);
    pca.components = q.transpose();
    pca.eigenvalues = Eigen::VectorXd::LinSpaced(Eigen::Index(kB), 1.0, 0.01);
    pca.explained_variance_ratio = pca.eigenvalues / pca.eigenvalues.sum();
    w.add_basis("pca", pca);
    store::Basis nmf;
    nmf.method = "nmf";
    nmf.wavelengths = wl;
    nmf.n = 24;
    nmf.components = Eigen::MatrixXd(2, Eigen::Index(kB));
    for (Eigen::Index b = 0; b < Eigen::Index(kB); ++b) {
      nmf.components(0, b) = 1.0 + 0.1 * double(b);
      nmf.components(1, b) = std::exp(-0.1 * double(b));
    }
    w.add_basis("nmf", nmf);

    store::Collection spd;
    spd.wavelengths = wl;
    spd.units = "relative";
    spd.names = {"flat", "ramp"};
    spd.values.resize(2 * kB);
    for (std::size_t b = 0; b < kB; ++b) spd.values[b] = 1.0f, spd.values[kB + b] = float(b + 1);
    w.add_collection("spd", spd);

    store::Grid g;
    g.wavelengths = wl;
    g.scale = 2.0;
    g.brdf.resize(kB * brdf::kMerlCells);
    for (std::size_t b = 0; b < kB; ++b)
      std::fill_n(g.brdf.begin() + std::ptrdiff_t(b * brdf::kMerlCells), brdf::kMerlCells, float(0.01 * double(b + 1)));
    w.add_grid("grid", g);
    std::fill(g.brdf.begin(), g.brdf.end(), 0.1f);
    g.scale = 1.0;
    w.add_grid("flat", g);
    store::Grid conf;  // grid's confidence: theta_h index / 89
    conf.wavelengths = WavelengthGrid({550.0});
    conf.units = "confidence";
    conf.brdf.resize(brdf::kMerlCells);
    for (std::size_t i = 0; i < brdf::kMerlCells; ++i) conf.brdf[i] = float(brdf::merl_cell(i).theta_h) / 89.0f;
    w.add_grid("grid.confidence", conf);

    w.create_samples("s", wl, "1/sr", {});
    const double d = pi / 180;
    // In the plane at theta_i = 45: mirror side (theta_o 30), light side (theta_o 20); then off theta_i, off the plane.
    const std::vector<double> angles = {45 * d, 0, 30 * d, pi, 45 * d, 1.0, 20 * d, 1.0,
                                        10 * d, 0, 30 * d, pi, 45 * d, 0,   30 * d, pi / 2};
    std::vector<float> values(4 * kB);
    for (std::size_t i = 0; i < 4; ++i)
      for (std::size_t b = 0; b < kB; ++b) values[i * kB + b] = float(10 * (i + 1) + b);
    w.append_samples("s", angles, values);
    w.commit();
    service_ = new view::Service(store::Store::open(path_));
  }
  static void TearDownTestSuite() {
    delete service_;
    delete dir_;
  }
  static view::Response get(const std::string& path, const view::Query& q = {}) { return service_->get(path, q); }

  static inline test::ScratchDir* dir_ = nullptr;
  static inline std::filesystem::path path_;
  static inline view::Service* service_ = nullptr;
};

store::PngImage decode(const view::Response& r, const std::filesystem::path& dir) {
  const auto p = dir / "r.png";
  std::ofstream(p, std::ios::binary) << r.body;
  return store::read_png(p);
}

TEST_F(ViewService, ListsEveryObjectOfTheStore) {
  const view::Response r = get("/api/store");
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.content_type, "application/json");
  for (const char* s : {"\"file\":\"view.h5\"", "{\"name\":\"img\",\"width\":6,\"height\":4,\"bands\":31",
                        "{\"name\":\"spd\",\"size\":2,\"bands\":31}", "{\"name\":\"grid\",\"bands\":31",
                        "{\"name\":\"flat\",\"bands\":31", "{\"name\":\"s\",\"size\":4,\"bands\":31",
                        "{\"name\":\"nmf\",\"method\":\"nmf\",\"k\":2,\"bands\":31}",
                        "{\"name\":\"pca\",\"method\":\"pca\",\"k\":3,\"bands\":31}"})
    EXPECT_NE(r.body.find(s), std::string::npos) << s << " not in " << r.body;
}

TEST_F(ViewService, SpectrumIsThePixelAsWritten) {
  for (const auto& [x, y] : {std::pair<std::size_t, std::size_t>{0, 0}, {4, 2}, {5, 3}}) {
    const view::Response r =
        get("/api/image/spectrum", {{"name", "img"}, {"x", std::to_string(x)}, {"y", std::to_string(y)}});
    ASSERT_EQ(r.status, 200) << r.body;
    const std::vector<double> v = json_array_of(r.body, "values"), wl = json_array_of(r.body, "wavelengths");
    ASSERT_EQ(v.size(), kB);
    ASSERT_EQ(wl.size(), kB);
    EXPECT_EQ(wl.front(), 420);
    EXPECT_EQ(wl.back(), 720);
    // The store keeps masked pixels as zeros (docs/store-format.md).
    const bool masked = x == 5 && y == 3;
    for (std::size_t b = 0; b < kB; ++b)
      EXPECT_FLOAT_EQ(float(v[b]), masked ? 0.0f : value(x, y, b)) << x << "," << y << " band " << b;
    EXPECT_NE(r.body.find(masked ? "\"valid\":false" : "\"valid\":true"), std::string::npos);
  }
}

TEST_F(ViewService, PcaReconstructionIsTheProjectionOntoTheFirstKComponents) {
  const store::Basis b = store::Store::open(path_).read_basis("pca");
  Eigen::VectorXd x(static_cast<Eigen::Index>(kB));
  for (std::size_t i = 0; i < kB; ++i) x[Eigen::Index(i)] = value(2, 1, i);
  for (const int k : {0, 1, 3}) {
    const view::Response r = get("/api/image/spectrum",
                                 {{"name", "img"}, {"x", "2"}, {"y", "1"}, {"basis", "pca"}, {"k", std::to_string(k)}});
    ASSERT_EQ(r.status, 200) << r.body;
    const std::vector<double> got = json_array_of(r.body, "values", 1);
    ASSERT_EQ(got.size(), kB);
    const Eigen::MatrixXd c = b.components.topRows(k);
    Eigen::VectorXd want = b.mean;
    for (Eigen::Index j = 0; j < k; ++j) want += c.row(j).dot(x - b.mean) * c.row(j).transpose();
    for (std::size_t i = 0; i < kB; ++i) EXPECT_NEAR(got[i], want[Eigen::Index(i)], 1e-12);
    EXPECT_NEAR(test::json_number(r.body, "l2_error"), (x - want).norm(), 1e-12);
    EXPECT_NEAR(test::json_number(r.body, "relative_error"), (x - want).norm() / x.norm(), 1e-12);
  }
}

TEST_F(ViewService, NmfReconstructionIsTheNonNegativeLeastSquaresFit) {
  const store::Basis b = store::Store::open(path_).read_basis("nmf");
  Eigen::VectorXd x(static_cast<Eigen::Index>(kB));
  for (std::size_t i = 0; i < kB; ++i) x[Eigen::Index(i)] = value(1, 3, i);
  const Eigen::VectorXd c = nnls_brute_force(b.components * b.components.transpose(), b.components * x);
  const Eigen::VectorXd want = b.components.transpose() * c;
  const view::Response r = get("/api/image/spectrum", {{"name", "img"}, {"x", "1"}, {"y", "3"}, {"basis", "nmf"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const std::vector<double> got = json_array_of(r.body, "values", 1);
  ASSERT_EQ(got.size(), kB);
  for (std::size_t i = 0; i < kB; ++i) EXPECT_NEAR(got[i], want[Eigen::Index(i)], 1e-9);
}

TEST_F(ViewService, PicturesDecodeToTheImageSizeWithMaskedPixelsMarked) {
  const view::Response rgb = get("/api/image/rgb", {{"name", "img"}, {"exposure", "0"}});
  ASSERT_EQ(rgb.status, 200) << rgb.body;
  EXPECT_EQ(rgb.content_type, "image/png");
  const store::PngImage p = decode(rgb, dir_->path());
  ASSERT_EQ(p.width, kW);
  ASSERT_EQ(p.height, kH);
  const std::size_t masked = 3 * kW + 5;
  EXPECT_EQ(p.samples[3 * masked], 128);
  EXPECT_EQ(p.samples[3 * masked + 1], 0);

  // A flat spectrum from the store lights the image exactly as the CIE illuminant E does.
  const view::Response e = get("/api/image/rgb", {{"name", "img"}, {"illuminant", "E"}, {"exposure", "0"}});
  const view::Response flat =
      get("/api/image/rgb", {{"name", "img"}, {"illuminant", "collection:spd:0"}, {"exposure", "0"}});
  ASSERT_EQ(flat.status, 200) << flat.body;
  EXPECT_EQ(decode(e, dir_->path()).samples, decode(flat, dir_->path()).samples);
  const view::Response ramp =
      get("/api/image/rgb", {{"name", "img"}, {"illuminant", "collection:spd:1"}, {"exposure", "0"}});
  ASSERT_EQ(ramp.status, 200);

  // One band: values grow with x and y, so the brightest valid pixel is white and the darkest is the least bright.
  const view::Response band = get("/api/image/band", {{"name", "img"}, {"band", "7"}});
  ASSERT_EQ(band.status, 200) << band.body;
  const store::PngImage g = decode(band, dir_->path());
  ASSERT_EQ(g.width, kW);
  EXPECT_EQ(g.samples[3 * (2 * kW + 5)], 255);  // the largest valid value (x 5, y 2) is above the 99th percentile
  for (std::size_t x = 1; x < kW; ++x) EXPECT_GT(g.samples[3 * x], g.samples[3 * (x - 1)]) << x;
  EXPECT_EQ(g.samples[3 * masked], 128);
}

TEST_F(ViewService, GridSlicesAndSphere) {
  const view::Response r = get("/api/grid/incidence", {{"name", "grid"}, {"theta_i", "45"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const std::vector<double> theta = json_array_of(r.body, "theta_o");
  ASSERT_EQ(theta.size(), 179u);
  EXPECT_EQ(theta.front(), -89);
  EXPECT_EQ(theta.back(), 89);
  // Row 0 of values: every band b holds 0.01 (b + 1) times the grid's scale of 2.
  const std::size_t at = r.body.find("\"values\":[[") + 11;
  std::stringstream row(r.body.substr(at, r.body.find(']', at) - at));
  std::string item;
  for (std::size_t b = 0; std::getline(row, item, ','); ++b)
    EXPECT_NEAR(std::stod(item), 0.02 * double(b + 1), 1e-6) << b;

  const view::Response s = get("/api/grid/sphere", {{"name", "grid"}});
  ASSERT_EQ(s.status, 200) << s.body;
  const store::PngImage p = decode(s, dir_->path());
  EXPECT_EQ(p.width, 256u);
  EXPECT_EQ(p.height, 256u);
  EXPECT_EQ(p.samples[0], 24);  // background

  // A spectrally flat constant BRDF f = 0.1 under D65 is grey; a light of irradiance pi from theta 45, phi 135
  // makes pixel (128, 128) pi f (n . l) in linear sRGB.
  const store::PngImage flat = decode(get("/api/grid/sphere", {{"name", "flat"}}), dir_->path());
  const double x = 128.5 / 128 - 1, y = 1 - 128.5 / 128;
  const Eigen::Vector3d n(x, y, std::sqrt(1 - x * x - y * y)), l(-0.5, 0.5, std::sqrt(0.5));
  const double want = 255 * srgb_encode(pi * 0.1 * n.dot(l));
  for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(flat.samples[3 * (128 * 256 + 128) + c], want, 1.0) << c;
}

TEST_F(ViewService, AGridWithAConfidenceBesideItOffersItsSlice) {
  const view::Response l = get("/api/store");
  EXPECT_NE(l.body.find("\"confidence\":\"grid.confidence\""), std::string::npos) << l.body;
  const view::Response r = get("/api/grid/incidence", {{"name", "grid"}, {"theta_i", "45"}});
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_NE(r.body.find("\"confidence_grid\":\"grid.confidence\""), std::string::npos);
  const std::vector<double> conf = json_array_of(r.body, "confidence");
  ASSERT_EQ(conf.size(), 179u);
  EXPECT_NEAR(conf[89 + 45], 0.0, 1e-7);        // the mirror direction: theta_h = 0
  EXPECT_NEAR(conf[89 - 45], 63.0 / 89, 1e-6);  // retro-reflection: theta_h = 45 degrees, index 63
  const view::Response f = get("/api/grid/incidence", {{"name", "flat"}, {"theta_i", "45"}});
  EXPECT_EQ(f.body.find("confidence"), std::string::npos);
}

TEST_F(ViewService, SampleScatterKeepsExactlyThePlaneAtThetaI) {
  const view::Response r =
      get("/api/samples/incidence", {{"name", "s"}, {"theta_i", "45"}, {"eps", "1"}, {"band", "3"}});
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_NE(r.body.find("\"points\":[[30.0,13.0],[-20.0,23.0]]"), std::string::npos) << r.body;
  EXPECT_EQ(test::json_number(r.body, "scanned"), 4);
  EXPECT_EQ(test::json_number(r.body, "wavelength"), 450);
}

TEST_F(ViewService, AssetsAreServedAndNothingElse) {
  const view::Response page = get("/");
  ASSERT_EQ(page.status, 200);
  EXPECT_EQ(page.content_type, "text/html; charset=utf-8");
  EXPECT_NE(page.body.find("/viewer.js"), std::string::npos);
  EXPECT_EQ(get("/viewer.js").status, 200);
  EXPECT_EQ(get("/viewer.css").status, 200);
  for (const char* p : {"/../view.h5", "/index.html/../../etc/passwd", "/etc/passwd", "/api", "/api/image", "/view.h5"})
    EXPECT_EQ(get(p).status, 404) << p;
}

TEST_F(ViewService, MalformedRequestsGetFourHundredsWithOneLine) {
  const std::vector<std::tuple<std::string, view::Query, int, std::string>> cases = {
      {"/api/image/spectrum", {{"x", "1"}, {"y", "1"}}, 400, "missing parameter 'name'"},
      {"/api/image/spectrum", {{"name", "nope"}, {"x", "1"}, {"y", "1"}}, 404, "view.h5: no image 'nope'"},
      {"/api/image/spectrum", {{"name", "../img"}, {"x", "1"}, {"y", "1"}}, 404, "no image '../img'"},
      {"/api/image/spectrum", {{"name", "/images/img"}, {"x", "1"}, {"y", "1"}}, 404, "no image"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "6"}, {"y", "1"}}, 400, "'x' = 6 is out of range"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "-1"}, {"y", "1"}}, 400, "not a whole number"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "1e3"}, {"y", "1"}}, 400, "not a whole number"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "1"}}, 400, "missing parameter 'y'"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "1"}, {"y", "1"}, {"basis", "zz"}}, 404, "no basis 'zz'"},
      {"/api/image/spectrum", {{"name", "img"}, {"x", "1"}, {"y", "1"}, {"basis", "pca"}, {"k", "4"}}, 400, "'k' = 4"},
      {"/api/image/band", {{"name", "img"}, {"band", "31"}}, 400, "'band' = 31 is out of range"},
      {"/api/image/rgb", {{"name", "img"}, {"illuminant", "/etc/passwd"}}, 400, "illuminant '/etc/passwd'"},
      {"/api/image/rgb", {{"name", "img"}, {"illuminant", "../spd.csv"}}, 400, "illuminant"},
      {"/api/image/rgb", {{"name", "img"}, {"illuminant", "collection:nope:0"}}, 404, "no collection 'nope'"},
      {"/api/image/rgb", {{"name", "img"}, {"illuminant", "collection:spd:2"}}, 400, "has 2 spectra"},
      {"/api/image/rgb", {{"name", "img"}, {"exposure", "nan"}}, 400, "'exposure' is not a number"},
      {"/api/image/rgb", {{"name", "img"}, {"exposure", "100"}}, 400, "outside [-64, 64]"},
      {"/api/grid/incidence", {{"name", "img"}}, 404, "no grid 'img'"},
      {"/api/grid/incidence", {{"name", "grid"}, {"theta_i", "95"}}, 400, "'theta_i' = 95"},
      {"/api/samples/incidence", {{"name", "s"}, {"eps", "0"}}, 400, "'eps' = 0"},
      {"/api/samples/incidence", {{"name", "grid"}}, 404, "no set of samples 'grid'"},
  };
  for (const auto& [path, q, status, text] : cases) {
    const view::Response r = get(path, q);
    EXPECT_EQ(r.status, status) << path << " " << r.body;
    EXPECT_NE(r.body.find(text), std::string::npos) << path << ": '" << text << "' not in '" << r.body << "'";
    EXPECT_EQ(r.body.find('\n'), std::string::npos) << r.body;
    EXPECT_EQ(r.content_type, "text/plain; charset=utf-8");
  }
}

}  // namespace

TEST(ViewServiceLive, KeepsServingWhileAnotherWriterCommitsAndShowsTheNewState) {
  test::ScratchDir dir;
  const auto path = dir / "live.h5";
  auto image = [](float v) {
    store::Cube c;
    c.resize(2, 3, 4);
    std::fill(c.data.begin(), c.data.end(), v);
    c.wavelengths = WavelengthGrid::range(450, 600, 50);
    return c;
  };
  {
    store::StoreWriter w(path, {});
    w.add_image("a", image(1.0f));
    w.commit();
  }
  view::Service service(store::Store::open(path));
  const view::Query pixel = {{"name", "a"}, {"x", "1"}, {"y", "1"}};
  ASSERT_EQ(service.get("/api/image/spectrum", pixel).status, 200);
  EXPECT_NE(service.get("/api/image/spectrum", pixel).body.find("\"values\":[1.0,1.0,1.0,1.0]"), std::string::npos);
  {
    store::StoreWriter w(path, {.replace = true});
    w.add_image("a", image(2.0f));
    w.add_image("b", image(3.0f));
    w.commit();
  }
  const view::Response listing = service.get("/api/store", {});
  ASSERT_EQ(listing.status, 200);
  EXPECT_NE(listing.body.find("{\"name\":\"b\""), std::string::npos) << listing.body;
  const view::Response r = service.get("/api/image/spectrum", pixel);
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_NE(r.body.find("\"values\":[2.0,2.0,2.0,2.0]"), std::string::npos) << r.body;
}
