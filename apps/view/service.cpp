#include "apps/view/service.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <regex>

#include "apps/common.h"
#include "specula/acquire/incidence.h"
#include "specula/acquire/prior_output.h"
#include "specula/codec/grid_slice.h"
#include "specula/codec/render.h"
#include "specula/codec/spectral_grid.h"
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

using Json = app::Json;

Json json_values(std::span<const float> v) { return Json(std::vector<double>(v.begin(), v.end())); }

Json json_wavelengths(const WavelengthGrid& g) { return app::json_numbers(g.values()); }

Response json(const Json& j) {
  return {200, "application/json", j.dump(-1, ' ', false, Json::error_handler_t::replace)};
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
      confidence_.reset();
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
  Json images = Json::array(), collections = Json::array(), grids = Json::array(), samples = Json::array(),
       bases = Json::array();
  for (const auto& n : store_.images()) {
    const store::ImageInfo i = store_.image_info(n);
    images.push_back({{"name", n},
                      {"width", i.width},
                      {"height", i.height},
                      {"bands", i.bands},
                      {"units", i.units},
                      {"wavelengths", json_wavelengths(i.wavelengths)}});
  }
  for (const auto& n : store_.collections()) {
    const store::CollectionInfo c = store_.collection_info(n);
    collections.push_back({{"name", n}, {"size", c.size}, {"bands", c.bands}});
  }
  const std::vector<std::string> grid_names = store_.grids();
  for (const auto& n : grid_names) {
    const store::GridInfo g = store_.grid_info(n);
    Json entry = {{"name", n}, {"bands", g.bands}, {"wavelengths", json_wavelengths(g.wavelengths)}};
    if (std::ranges::find(grid_names, acquire::confidence_name(n)) != grid_names.end())
      entry["confidence"] = acquire::confidence_name(n);
    grids.push_back(entry);
  }
  for (const auto& n : store_.samples()) {
    const store::SamplesInfo i = store_.samples_info(n);
    samples.push_back(
        {{"name", n}, {"size", i.size}, {"bands", i.bands}, {"wavelengths", json_wavelengths(i.wavelengths)}});
  }
  for (const auto& n : store_.bases()) {
    const store::Basis b = store_.read_basis(n);
    bases.push_back({{"name", n}, {"method", b.method}, {"k", b.k()}, {"bands", b.bands()}});
  }
  return json({{"file", store_.label()},
               {"images", images},
               {"collections", collections},
               {"grids", grids},
               {"samples", samples},
               {"bases", bases}});
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

const store::Grid& Service::confidence(const std::string& name) {
  if (!confidence_ || confidence_name_ != name) {
    confidence_.reset();
    confidence_ = std::make_unique<store::Grid>(store_.read_grid(name));
    confidence_name_ = name;
  }
  return *confidence_;
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
  const std::vector<std::uint8_t> rgb = band_preview(cube.data, cube.bands, band, cube.mask);
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
  Json j = {{"image", name},
            {"x", x},
            {"y", y},
            {"valid", valid},
            {"units", info.units},
            {"wavelengths", json_wavelengths(info.wavelengths)},
            {"values", json_values(v)}};
  if (const auto it = q.find("basis"); it != q.end() && !it->second.empty() && valid) {
    const std::string bname = object({{"name", it->second}}, store_.bases(), "basis", store_.label());
    const store::Basis b = store_.read_basis(bname);
    try {
      // PCA: the first k components, k = 0 showing the mean alone; NMF: all of them.
      const bool pca = stats::basis_method(b, "'" + bname + "'") == stats::BasisMethod::pca;
      const std::optional<std::size_t> k =
          pca ? std::optional<std::size_t>(std::size_t(number(q, "k", double(b.k()), 0, double(b.k())))) : std::nullopt;
      const stats::SpectrumReconstruction r = stats::reconstruct_spectrum(b, "'" + bname + "'", k, v, info.wavelengths,
                                                                          store_.label() + ": image '" + name + "'");
      j["reconstruction"] = {{"basis", bname},
                             {"method", b.method},
                             {"k", r.k},
                             {"values", app::json_numbers(r.values)},
                             {"l2_error", r.l2_error},
                             {"relative_error", r.relative_error}};
    } catch (const InputError& e) {
      throw HttpError(400, e.what());
    }
  }
  return json(j);
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
  const codec::GridSlice slice = codec::incidence_slice(g, theta_i);
  Json values = Json::array();
  for (std::size_t a = 0; a < slice.theta_o_deg.size(); ++a)
    values.push_back(app::json_numbers(std::span(slice.values).subspan(a * slice.bands, slice.bands)));
  Json out = {{"grid", name},
              {"theta_i", theta_i * 180 / pi},
              {"wavelengths", json_wavelengths(g.wavelengths)},
              {"theta_o", slice.theta_o_deg},
              {"values", values}};
  // A reconstruction with a prior has its per-cell confidence beside it (docs/prior.md): the same slice of it.
  const std::string conf = acquire::confidence_name(name);
  const std::vector<std::string> grid_names = store_.grids();
  if (std::ranges::find(grid_names, conf) != grid_names.end()) {
    const codec::GridSlice c = codec::incidence_slice(confidence(conf), theta_i);
    if (c.bands != 1) throw HttpError(500, conf + " is not a one-band confidence grid");
    out["confidence_grid"] = conf;
    out["confidence"] = app::json_numbers(c.values);
  }
  return json(out);
}

Response Service::samples_incidence(const Query& q) {
  const std::string name = object(q, store_.samples(), "set of samples", store_.label());
  const store::SamplesInfo info = store_.samples_info(name);
  const double theta_i = number(q, "theta_i", 45, 0, 89) * pi / 180;
  const double eps = number(q, "eps", 2, 0.01, 20) * pi / 180;
  const std::size_t band = q.count("band") ? index(q, "band", info.bands, "band index") : info.bands / 2;
  const auto limit = std::size_t(number(q, "limit", 20000, 1, 1e6));
  const acquire::PlanePoints found =
      acquire::incidence_plane_points(store_, name, std::span(&theta_i, 1), eps, band, limit).front();
  Json points = Json::array();
  for (const acquire::PlanePoint& p : found.points)
    points.push_back({std::round(p.theta_o * 180 / pi * 1000) / 1000, p.value});
  return json({{"samples", name},
               {"theta_i", theta_i * 180 / pi},
               {"eps", eps * 180 / pi},
               {"band", band},
               {"wavelength", info.wavelengths[band]},
               {"scanned", found.scanned},
               {"points", points}});
}

}  // namespace specula::view
