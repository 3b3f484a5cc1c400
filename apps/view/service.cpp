#include "apps/view/service.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <regex>

#include "apps/common.h"
#include "specula/acquire/mapping.h"
#include "specula/codec/render.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/core/preview.h"
#include "specula/stats/project.h"
#include "specula/store/io/png_stack.h"

namespace specula::view {
namespace {

using std::numbers::pi;

// A request the client got wrong (400) or an object that does not exist (404).
struct HttpError : std::runtime_error {
  int status;
  HttpError(int s, const std::string& m) : std::runtime_error(m), status(s) {}
};

std::string required(const Query& q, const std::string& key) {
  const auto it = q.find(key);
  if (it == q.end() || it->second.empty()) throw HttpError(400, "missing parameter '" + key + "'");
  return it->second;
}

std::string optional_param(const Query& q, const std::string& key, const std::string& fallback) {
  const auto it = q.find(key);
  return it == q.end() || it->second.empty() ? fallback : it->second;
}

double number(const Query& q, const std::string& key, double fallback, double lo, double hi) {
  const auto it = q.find(key);
  if (it == q.end() || it->second.empty()) return fallback;
  double v = 0;
  const char* end = it->second.data() + it->second.size();
  const auto r = std::from_chars(it->second.data(), end, v);
  if (r.ec != std::errc() || r.ptr != end || !std::isfinite(v))
    throw HttpError(400, "parameter '" + key + "' is not a number: '" + it->second + "'");
  if (v < lo || v > hi)
    throw HttpError(400, fmt::format("parameter '{}' = {} is outside [{}, {}]", key, it->second, lo, hi));
  return v;
}

std::size_t index(const Query& q, const std::string& key, std::size_t size, const std::string& what) {
  const std::string s = required(q, key);
  std::size_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size())
    throw HttpError(400, "parameter '" + key + "' is not a whole number: '" + s + "'");
  if (v >= size)
    throw HttpError(
        400, fmt::format("parameter '{}' = {} is out of range: the {} runs from 0 to {}", key, v, what, size - 1));
  return v;
}

// The object `name` of a kind, checked against the store's own list: a name that is not listed (including any
// path such as ../x) never reaches HDF5.
std::string object(const Query& q, const std::vector<std::string>& listed, const std::string& kind,
                   const std::string& file) {
  const std::string name = required(q, "name");
  if (std::find(listed.begin(), listed.end(), name) == listed.end())
    throw HttpError(404, file + ": no " + kind + " '" + name + "'");
  return name;
}

std::string json_numbers(std::span<const float> v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += fmt::format("{}{}", i ? "," : "", v[i]);
  return s + "]";
}

std::string json_numbers(const Eigen::VectorXd& v) {
  return app::json_array(std::span<const double>(v.data(), std::size_t(v.size())));
}

std::string json_wavelengths(const WavelengthGrid& g) {
  std::vector<double> nm(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) nm[i] = g[i];
  return app::json_array(nm);
}

Response png(std::string bytes) { return {200, "image/png", std::move(bytes)}; }

std::string png_bytes(std::size_t w, std::size_t h, std::span<const std::uint8_t> rgb) {
  const std::vector<std::uint8_t> b = store::encode_png_rgb8(w, h, rgb);
  return std::string(b.begin(), b.end());
}

// An illuminant from the page: a CIE name, D<CCT/100>, blackbody:K, or spectrum INDEX of collection NAME in the
// store ("collection:NAME:INDEX"). Never a file path.
Eigen::VectorXd page_illuminant(const std::string& spec, const store::Store& st, const WavelengthGrid& grid) {
  static const std::regex from_store(R"(collection:([A-Za-z0-9_.+-]+):([0-9]+))");
  std::smatch m;
  if (!std::regex_match(spec, m, from_store)) {
    try {
      return parse_illuminant(spec, grid, IlluminantFiles::refused);
    } catch (const UsageError& e) {
      throw HttpError(400, std::string(e.what()) + ", or collection:NAME:INDEX");
    }
  }
  const auto listed = st.collections();
  if (std::find(listed.begin(), listed.end(), m[1].str()) == listed.end())
    throw HttpError(404, st.label() + ": no collection '" + m[1].str() + "' for the illuminant");
  const store::Collection c = st.read_collection(m[1].str());
  const std::size_t i = std::stoul(m[2].str());
  if (i >= c.size())
    throw HttpError(400, fmt::format("illuminant '{}': the collection has {} spectra", spec, c.size()));
  if (!c.wavelengths.approx_equal(grid))
    throw HttpError(
        400, "illuminant '" + spec + "' is on " + c.wavelengths.describe() + ", the image on " + grid.describe());
  Eigen::VectorXd v(Eigen::Index(grid.size()));
  for (std::size_t b = 0; b < grid.size(); ++b) v[Eigen::Index(b)] = c.values[i * c.bands() + b];
  return v;
}

}  // namespace

Service::Service(store::Store store) : store_(std::move(store)) {}

Response Service::get(const std::string& path, const Query& query) {
  std::lock_guard lock(mutex_);
  try {
    if (store_.stale()) {  // another process committed: serve the new state from now on
      store_ = store::Store::open(store_.path());
      image_.reset();
      grid_.reset();
      png_cache_.clear();
    }
    return dispatch(path, query);
  } catch (const HttpError& e) {
    return {e.status, "text/plain; charset=utf-8", e.what()};
  } catch (const UsageError& e) {
    return {400, "text/plain; charset=utf-8", e.what()};
  } catch (const std::exception& e) {
    return {500, "text/plain; charset=utf-8", e.what()};
  }
}

Response Service::dispatch(const std::string& path, const Query& q) {
  if (path == "/api/store") return store_listing();
  if (path == "/api/image/rgb") return image_rgb(q);
  if (path == "/api/image/band") return image_band(q);
  if (path == "/api/image/spectrum") return image_spectrum(q);
  if (path == "/api/grid/sphere") return grid_sphere(q);
  if (path == "/api/grid/incidence") return grid_incidence(q);
  if (path == "/api/samples/incidence") return samples_incidence(q);
  if (const auto a = asset(path)) return {200, a->first, a->second};
  throw HttpError(404, "no such page or endpoint: " + path);
}

Response Service::store_listing() {
  std::string s = "{\"file\":" + app::json_string(store_.label()) + ",\"images\":[";
  bool first = true;
  for (const auto& n : store_.images()) {
    const store::ImageInfo i = store_.image_info(n);
    s += fmt::format("{}{{\"name\":{},\"width\":{},\"height\":{},\"bands\":{},\"units\":{},\"wavelengths\":{}}}",
                     first ? "" : ",", app::json_string(n), i.width, i.height, i.bands, app::json_string(i.units),
                     json_wavelengths(i.wavelengths));
    first = false;
  }
  s += "],\"collections\":[";
  first = true;
  for (const auto& n : store_.collections()) {
    const store::CollectionInfo c = store_.collection_info(n);
    s += fmt::format("{}{{\"name\":{},\"size\":{},\"bands\":{}}}", first ? "" : ",", app::json_string(n), c.size,
                     c.bands);
    first = false;
  }
  s += "],\"grids\":[";
  first = true;
  for (const auto& n : store_.grids()) {
    const store::GridInfo g = store_.grid_info(n);
    s += fmt::format("{}{{\"name\":{},\"bands\":{},\"wavelengths\":{}}}", first ? "" : ",", app::json_string(n),
                     g.bands, json_wavelengths(g.wavelengths));
    first = false;
  }
  s += "],\"samples\":[";
  first = true;
  for (const auto& n : store_.samples()) {
    const store::SamplesInfo i = store_.samples_info(n);
    s += fmt::format("{}{{\"name\":{},\"size\":{},\"bands\":{},\"wavelengths\":{}}}", first ? "" : ",",
                     app::json_string(n), i.size, i.bands, json_wavelengths(i.wavelengths));
    first = false;
  }
  s += "],\"bases\":[";
  first = true;
  for (const auto& n : store_.bases()) {
    const store::Basis b = store_.read_basis(n);
    s += fmt::format("{}{{\"name\":{},\"method\":{},\"k\":{},\"bands\":{}}}", first ? "" : ",", app::json_string(n),
                     app::json_string(b.method), b.k(), b.bands());
    first = false;
  }
  return {200, "application/json", s + "]}"};
}

const store::Cube& Service::image(const std::string& name) {
  if (!image_ || image_name_ != name) {
    image_.reset();
    image_ = std::make_unique<store::Cube>(store_.read_image(name));
    image_name_ = name;
  }
  return *image_;
}

const store::Grid& Service::grid(const std::string& name) {
  if (!grid_ || grid_name_ != name) {
    grid_.reset();
    grid_ = std::make_unique<store::Grid>(store_.read_grid(name));
    grid_name_ = name;
  }
  return *grid_;
}

Response Service::image_rgb(const Query& q) {
  const std::string name = object(q, store_.images(), "image", store_.label());
  app::PreviewOptions o;
  const std::string illuminant = optional_param(q, "illuminant", "D65");
  o.exposure = optional_param(q, "exposure", "auto");
  if (o.exposure != "auto") number(q, "exposure", 0, -64, 64);
  const std::string key = "rgb\n" + name + "\n" + illuminant + "\n" + o.exposure;
  if (const auto it = png_cache_.find(key); it != png_cache_.end()) return png(it->second);
  const store::Cube& cube = image(name);
  PreviewSettings settings;
  settings.illuminant = page_illuminant(illuminant, store_, cube.wavelengths);
  settings.exposure_stops = parse_exposure(o.exposure);
  const Picture picture = app::render(cube, settings);
  const std::vector<std::uint8_t>& rgb = picture.srgb8;
  if (png_cache_.size() >= 16) png_cache_.clear();
  return png(png_cache_[key] = png_bytes(cube.width, cube.height, rgb));
}

Response Service::image_band(const Query& q) {
  const std::string name = object(q, store_.images(), "image", store_.label());
  const store::ImageInfo info = store_.image_info(name);
  const std::size_t band = index(q, "band", info.bands, "band index");
  const std::string key = fmt::format("band\n{}\n{}", name, band);
  if (const auto it = png_cache_.find(key); it != png_cache_.end()) return png(it->second);
  const store::Cube& cube = image(name);
  std::vector<float> v;
  v.reserve(cube.height * cube.width);
  for (std::size_t p = 0; p < cube.height * cube.width; ++p)
    if (cube.mask.empty() || cube.mask[p]) v.push_back(cube.data[p * cube.bands + band]);
  const double top = std::max(quantile(v, 0.99), 1e-30);
  std::vector<std::uint8_t> rgb(3 * cube.height * cube.width);
  for (std::size_t p = 0; p < cube.height * cube.width; ++p) {
    const double t = std::clamp(double(cube.data[p * cube.bands + band]) / top, 0.0, 1.0);
    const auto g = std::uint8_t(std::lround(255 * srgb_encode(t)));
    rgb[3 * p] = rgb[3 * p + 1] = rgb[3 * p + 2] = g;
  }
  paint_masked(rgb, cube.mask);
  if (png_cache_.size() >= 16) png_cache_.clear();
  return png(png_cache_[key] = png_bytes(cube.width, cube.height, rgb));
}

Response Service::image_spectrum(const Query& q) {
  const std::string name = object(q, store_.images(), "image", store_.label());
  const store::ImageInfo info = store_.image_info(name);
  const std::size_t x = index(q, "x", info.width, "image's x");
  const std::size_t y = index(q, "y", info.height, "image's y");
  std::vector<float> v(info.bands);
  const bool valid = store_.read_pixel(name, x, y, v);
  std::string s =
      fmt::format("{{\"image\":{},\"x\":{},\"y\":{},\"valid\":{},\"units\":{},\"wavelengths\":{},\"values\":{}",
                  app::json_string(name), x, y, valid ? "true" : "false", app::json_string(info.units),
                  json_wavelengths(info.wavelengths), json_numbers(v));
  if (const auto it = q.find("basis"); it != q.end() && !it->second.empty() && valid) {
    const std::string bname = object({{"name", it->second}}, store_.bases(), "basis", store_.label());
    const store::Basis b = store_.read_basis(bname);
    RowMatrixXd xv(1, Eigen::Index(v.size())), r(1, Eigen::Index(v.size()));
    for (std::size_t i = 0; i < v.size(); ++i) xv(0, Eigen::Index(i)) = v[i];
    std::size_t k = b.k();
    try {
      // PCA: the first k components, k = 0 showing the mean alone (the reconstruction from a zero coefficient);
      // NMF: all of them.
      const bool pca = stats::basis_method(b, "'" + bname + "'") == stats::BasisMethod::pca;
      if (pca) k = std::size_t(number(q, "k", double(b.k()), 0, double(b.k())));
      const stats::Projector projector(b, pca ? std::optional<long long>(std::max<std::size_t>(k, 1)) : std::nullopt,
                                       "'" + bname + "'");
      projector.check_wavelengths(info.wavelengths, store_.label() + ": image '" + name + "'");
      RowMatrixXd coef(1, Eigen::Index(projector.k()));
      projector.project(xv, coef);
      if (k == 0) coef.setZero();
      projector.reconstruct(coef, r);
    } catch (const InputError& e) {
      throw HttpError(400, e.what());
    }
    const double err = (xv - r).norm(), norm = xv.norm();
    s += fmt::format(
        ",\"reconstruction\":{{\"basis\":{},\"method\":{},\"k\":{},\"values\":{},\"l2_error\":{},\"relative_error\":{}}"
        "}",
        app::json_string(bname), app::json_string(b.method), k, json_numbers(Eigen::VectorXd(r.row(0).transpose())),
        err, norm > 0 ? err / norm : 0.0);
  }
  return {200, "application/json", s + "}"};
}

Response Service::grid_sphere(const Query& q) {
  const std::string name = object(q, store_.grids(), "grid", store_.label());
  const double exposure = number(q, "exposure", 0, -64, 64);
  const double theta = number(q, "light_theta", 45, 0, 89.9), phi = number(q, "light_phi", 135, -360, 360);
  const std::string illuminant = optional_param(q, "illuminant", "D65");
  const std::string key = fmt::format("sphere\n{}\n{}\n{}\n{}\n{}", name, exposure, theta, phi, illuminant);
  if (const auto it = png_cache_.find(key); it != png_cache_.end()) return png(it->second);
  const store::Grid& g = grid(name);
  const Eigen::VectorXd spd = page_illuminant(illuminant, store_, g.wavelengths);
  const double t = theta * pi / 180, p = phi * pi / 180;
  const std::size_t size = 256;
  const codec::SphereImage img =
      codec::render_sphere(g, spd, size, {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)});
  std::vector<std::uint8_t> out(3 * size * size);
  encode_srgb8(img.linear, img.covered, exposure, out);
  if (png_cache_.size() >= 16) png_cache_.clear();
  return png(png_cache_[key] = png_bytes(size, size, out));
}

Response Service::grid_incidence(const Query& q) {
  const std::string name = object(q, store_.grids(), "grid", store_.label());
  const double theta_i = number(q, "theta_i", 45, 0, 89) * pi / 180;
  const store::Grid& g = grid(name);
  const std::size_t bands = g.bands();
  std::string angles = "[", values = "[";
  for (int deg = -89; deg <= 89; ++deg) {
    const double to = std::abs(deg) * pi / 180;
    // Negative: the viewer on the light's side (phi_d = 0); positive: towards the mirror direction.
    const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::StdAngles{theta_i, 0.0, to, deg > 0 ? pi : 0.0}));
    std::string row = "[";
    for (std::size_t b = 0; b < bands; ++b) {
      const float v = g.brdf[b * brdf::kMerlCells + cell];
      row += (b ? "," : "") + (v < 0 ? std::string("null") : fmt::format("{}", double(v) * g.scale));
    }
    angles += fmt::format("{}{}", deg == -89 ? "" : ",", deg);
    values += (deg == -89 ? "" : ",") + row + "]";
  }
  return {200, "application/json",
          fmt::format("{{\"grid\":{},\"theta_i\":{},\"wavelengths\":{},\"theta_o\":{}],\"values\":{}]}}",
                      app::json_string(name), theta_i * 180 / pi, json_wavelengths(g.wavelengths), angles, values)};
}

Response Service::samples_incidence(const Query& q) {
  const std::string name = object(q, store_.samples(), "set of samples", store_.label());
  const store::SamplesInfo info = store_.samples_info(name);
  const double theta_i = number(q, "theta_i", 45, 0, 89) * pi / 180;
  const double eps = number(q, "eps", 2, 0.01, 20) * pi / 180;
  const std::size_t band = q.count("band") ? index(q, "band", info.bands, "band index") : info.bands / 2;
  const auto limit = std::size_t(number(q, "limit", 20000, 1, 1e6));
  std::string points = "[";
  std::size_t found = 0, scanned = 0;
  const std::size_t block = std::max<std::size_t>(info.chunk_rows, 65536);
  std::vector<double> angles;
  std::vector<float> values;
  // Streams the samples in blocks; stops once `limit` points are found.
  for (std::size_t first = 0; first < info.size && found < limit; first += block) {
    const std::size_t n = std::min(block, info.size - first);
    angles.resize(4 * n);
    store_.read_samples(name, first, n, angles, {});
    scanned += n;
    // Angles first; a block's values are read only when some of its samples lie in the plane.
    bool have_values = false;
    for (std::size_t i = 0; i < n && found < limit; ++i) {
      const auto x = acquire::incidence_plane_angle(
          acquire::iso_angles({angles[4 * i], angles[4 * i + 1], angles[4 * i + 2], angles[4 * i + 3]}), theta_i, eps);
      if (!x) continue;
      if (!have_values) {
        values.resize(n * info.bands);
        store_.read_samples(name, first, n, {}, values);
        have_values = true;
      }
      points += fmt::format("{}[{:.3f},{}]", found ? "," : "", *x * 180 / pi, values[i * info.bands + band]);
      ++found;
    }
  }
  return {
      200, "application/json",
      fmt::format(
          "{{\"samples\":{},\"theta_i\":{},\"eps\":{},\"band\":{},\"wavelength\":{},\"scanned\":{},\"points\":{}]}}",
          app::json_string(name), theta_i * 180 / pi, eps * 180 / pi, band, info.wavelengths[band], scanned, points)};
}

}  // namespace specula::view
