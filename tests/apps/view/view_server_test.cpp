// `specula view` as a process: it listens on loopback, answers over real HTTP (malformed and traversing requests
// get 4xx), refuses bad options with one line; and, in headless Chromium (tests/apps/view/e2e), the spectrum the
// page plots under the mouse is the one written into the store.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <regex>
#include <string>
#include <vector>

#include "specula/core/brdf_geometry.h"
#include "specula/store/store.h"
#include "test_support.h"

// After Eigen (through store.h): httplib pulls in <resolv.h>, whose _res macro breaks Eigen headers.
#include <httplib.h>

using namespace specula;

namespace {

constexpr std::size_t kW = 40, kH = 30, kB = 31;

float value(std::size_t x, std::size_t y, std::size_t b) {
  return float(0.05 + 0.01 * double(x % 7) + 0.02 * double(y % 5) + 0.4 * std::sin(0.1 * double(b * (x + 1))) * 0.5 +
               0.2);
}

std::filesystem::path make_store(const std::filesystem::path& dir) {
  const auto path = dir / "e2e.h5";
  store::StoreWriter w(path, {});
  store::Cube c;
  c.resize(kH, kW, kB);
  c.wavelengths = WavelengthGrid::range(420, 720, 10);
  c.units = "reflectance";
  for (std::size_t y = 0; y < kH; ++y)
    for (std::size_t x = 0; x < kW; ++x)
      for (std::size_t b = 0; b < kB; ++b) c.pixel(y, x)[b] = value(x, y, b);
  w.add_image("scene", c);
  store::Grid g;  // a reconstruction and its confidence (theta_h index / 89)
  g.wavelengths = WavelengthGrid({500.0, 600.0});
  g.brdf.assign(2 * brdf::kMerlCells, 0.1f);
  w.add_grid("rec", g);
  g.wavelengths = WavelengthGrid({550.0});
  g.units = "confidence";
  g.brdf.resize(brdf::kMerlCells);
  for (std::size_t i = 0; i < brdf::kMerlCells; ++i) g.brdf[i] = float(brdf::merl_cell(i).theta_h) / 89.0f;
  w.add_grid("rec.confidence", g);
  w.commit();
  return path;
}

// `specula view STORE --port 0` running in the background; stopped (SIGTERM) on destruction.
class Server {
 public:
  explicit Server(const std::filesystem::path& store) {
    int fd[2];
    if (pipe(fd) != 0) throw std::runtime_error("pipe");
    pid_ = fork();
    if (pid_ == 0) {
      dup2(fd[1], 1);
      close(fd[0]);
      execl(SPECULA_BINARY, SPECULA_BINARY, "view", store.c_str(), "--port", "0", static_cast<char*>(nullptr));
      _exit(127);
    }
    close(fd[1]);
    out_ = fdopen(fd[0], "r");
    char line[512] = {};
    if (!std::fgets(line, sizeof line, out_)) return;
    first_line_ = line;
    std::smatch m;
    if (std::regex_search(first_line_, m, std::regex(R"(http://127\.0\.0\.1:([0-9]+)/)")))
      port_ = std::stoi(m[1].str());
  }
  ~Server() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    if (out_) std::fclose(out_);
  }
  int port() const { return port_; }
  const std::string& first_line() const { return first_line_; }

 private:
  pid_t pid_ = -1;
  std::FILE* out_ = nullptr;
  std::string first_line_;
  int port_ = 0;
};

TEST(ViewServer, ListensOnLoopbackAndAnswersMalformedRequestsWithFourHundreds) {
  test::ScratchDir dir;
  const Server server(make_store(dir.path()));
  ASSERT_GT(server.port(), 0) << server.first_line();
  httplib::Client client("127.0.0.1", server.port());
  auto ok = client.Get("/api/image/spectrum?name=scene&x=3&y=2");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  EXPECT_NE(ok->body.find("\"x\":3,\"y\":2,\"valid\":true"), std::string::npos) << ok->body;
  EXPECT_EQ(client.Get("/")->status, 200);
  for (const char* bad : {"/api/image/spectrum?name=..%2Fe2e.h5&x=1&y=1", "/api/image/spectrum?name=scene&x=40&y=0",
                          "/api/image/band?name=scene&band=-1", "/%2e%2e/%2e%2e/etc/passwd", "/../../etc/passwd",
                          "/api/image/rgb?name=scene&illuminant=..%2F..%2Fetc%2Fpasswd"}) {
    auto r = client.Get(bad);
    ASSERT_TRUE(r) << bad;
    EXPECT_GE(r->status, 400) << bad;
    EXPECT_LT(r->status, 500) << bad << ": " << r->body;
    EXPECT_EQ(r->body.find("root:"), std::string::npos) << bad;
  }
}

TEST(ViewServer, RefusesBadOptionsAndMissingStoresWithOneLine) {
  test::ScratchDir dir;
  const auto store = make_store(dir.path());
  const auto port = test::run_specula("view '" + store.string() + "' --port 70000");
  EXPECT_EQ(port.status, 1) << port.output;
  EXPECT_NE(port.output.find("--port must be 0 to 65535"), std::string::npos) << port.output;
  const auto missing = test::run_specula("view '" + (dir.path() / "none.h5").string() + "' --port 0");
  EXPECT_EQ(missing.status, 1) << missing.output;
  EXPECT_NE(missing.output.find("none.h5"), std::string::npos) << missing.output;
}

// The page in headless Chromium: hover a pixel, read the plotted spectrum (each point carries its value).
TEST(ViewServer, BrowserPlotsTheSpectrumUnderTheMouse) {
  const std::filesystem::path e2e = std::filesystem::path(SPECULA_SOURCE_DIR) / "tests/apps/view/e2e";
  if (!std::filesystem::exists("/usr/bin/chromium"))
    GTEST_SKIP() << "Debian's chromium is not installed (scripts/setup-deps --browser installs it)";
  ASSERT_TRUE(std::filesystem::exists(e2e / "node_modules/playwright-core"))
      << "playwright-core is missing: run 'npm ci' in " << e2e << " (scripts/test does)";
  test::ScratchDir dir;
  const Server server(make_store(dir.path()));
  ASSERT_GT(server.port(), 0) << server.first_line();
  const std::size_t x = 23, y = 17;
  const std::string shot = std::getenv("SPECULA_VIEW_SCREENSHOT") ? std::getenv("SPECULA_VIEW_SCREENSHOT") : "";
  const auto r = test::run_shell("cd '" + e2e.string() +
                                 "' && node hover.mjs http://127.0.0.1:" + std::to_string(server.port()) + "/ scene " +
                                 std::to_string(x) + " " + std::to_string(y) + (shot.empty() ? "" : " '" + shot + "'"));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::size_t at = r.output.find("\"points\":[[");
  ASSERT_NE(at, std::string::npos) << r.output;
  std::vector<std::pair<double, double>> points;
  const std::regex pair(R"(\[([-0-9.e]+),([-0-9.e]+)\])");
  const std::string body = r.output.substr(at + 10);
  for (auto it = std::sregex_iterator(body.begin(), body.end(), pair); it != std::sregex_iterator(); ++it)
    points.emplace_back(std::stod((*it)[1].str()), std::stod((*it)[2].str()));
  ASSERT_EQ(points.size(), kB) << r.output;
  for (std::size_t b = 0; b < kB; ++b) {
    EXPECT_DOUBLE_EQ(points[b].first, 420.0 + 10.0 * double(b));
    EXPECT_NEAR(points[b].second, value(x, y, b), 1e-6) << "band " << b;
  }
}

// The page offers a grid's confidence: plotted along the slice (the values the store holds), and hidden on request.
TEST(ViewServer, BrowserPlotsAGridsConfidence) {
  const std::filesystem::path e2e = std::filesystem::path(SPECULA_SOURCE_DIR) / "tests/apps/view/e2e";
  if (!std::filesystem::exists("/usr/bin/chromium"))
    GTEST_SKIP() << "Debian's chromium is not installed (scripts/setup-deps --browser installs it)";
  ASSERT_TRUE(std::filesystem::exists(e2e / "node_modules/playwright-core"))
      << "playwright-core is missing: run 'npm ci' in " << e2e << " (scripts/test does)";
  test::ScratchDir dir;
  const Server server(make_store(dir.path()));
  ASSERT_GT(server.port(), 0) << server.first_line();
  const auto r = test::run_shell(
      "cd '" + e2e.string() + "' && node confidence.mjs http://127.0.0.1:" + std::to_string(server.port()) + "/ rec");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"hidden\":true"), std::string::npos) << r.output;
  const std::size_t at = r.output.find("\"points\":[[");
  ASSERT_NE(at, std::string::npos) << r.output;
  std::map<int, double> conf;
  const std::regex pair(R"(\[([-0-9.e]+),([-0-9.e]+)\])");
  const std::string body = r.output.substr(at + 10);
  for (auto it = std::sregex_iterator(body.begin(), body.end(), pair); it != std::sregex_iterator(); ++it)
    conf[std::stoi((*it)[1].str())] = std::stod((*it)[2].str());
  EXPECT_EQ(conf.size(), 179u) << r.output;
  EXPECT_NEAR(conf[45], 0.0, 1e-6);         // theta_i 45: the mirror direction, theta_h = 0
  EXPECT_NEAR(conf[-45], 63.0 / 89, 1e-6);  // retro-reflection, theta_h = 45 degrees: index 63
}

}  // namespace
