// specula coefficients: coefficient maps of chosen images on a PCA basis (eq 7.2) or an NMF basis (exact NNLS),
// streamed block by block from the store into chunked /coefficients/<name> datasets, with pictures of the maps.
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "apps/canvas.h"
#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/core/parallel.h"
#include "specula/stats/project.h"
#include "specula/store/block_reader.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

namespace fs = std::filesystem;

struct CoefficientsOptions {
  std::string store;
  std::string basis;
  std::vector<std::string> images;
  long long k = 0;
  std::string name;
  std::string plots;
  bool replace = false;
  bool json = false;
};

// What one image's map came to: the reconstruction error of its valid pixels from the coefficients written.
struct MapResult {
  std::string name, image;
  std::size_t height = 0, width = 0;
  std::uint64_t valid = 0;
  double sum_sq = 0;              // ||X||^2 over the valid pixels
  stats::ProjectionError error;  // of the reconstruction from the coefficients
  std::string plot;
};

// One figure per map: its k coefficient images side by side (at most four to a row), each above its own colour
// bar: NMF coefficients from 0 (black) to their 99th percentile, PCA ones blue-white-red around 0 to +-99th
// percentile of |c|. Masked pixels are grey.
void write_plot(const fs::path& path, const store::Store& s, const std::string& name) {
  const store::CoefficientsInfo info = s.coefficients_info(name);
  const std::size_t h = info.height, w = info.width, k = info.k;
  std::vector<float> c(h * w * k);
  std::vector<std::uint8_t> mask(h * w);
  s.read_coefficient_rows(name, 0, h, c, mask);
  const bool nmf = info.method == "nmf";
  const std::size_t sc = font_scale(w), pad = 4 * sc, gap = 12 * sc, line = 10 * sc;
  const std::size_t columns = std::min<std::size_t>(k, 4), rows = (k + columns - 1) / columns;
  std::vector<double> range(k, 0.0);
  std::size_t panel_w = w;
  for (std::size_t j = 0; j < k; ++j) {
    std::vector<float> v;
    for (std::size_t p = 0; p < h * w; ++p)
      if (mask[p]) v.push_back(nmf ? c[p * k + j] : std::abs(c[p * k + j]));
    range[j] = quantile(v, 0.99);
    const std::string hi = number_label(range[j]), lo = nmf ? "0" : number_label(-range[j]);
    panel_w = std::max(panel_w, bar_min_width("", lo, hi, sc));
  }
  const std::size_t cell_h = line + h + pad + bar_height(sc);
  Canvas canvas(2 * pad + columns * panel_w + (columns - 1) * gap, pad + rows * (cell_h + pad));
  for (std::size_t j = 0; j < k; ++j) {
    const std::size_t x0 = pad + (j % columns) * (panel_w + gap), y0 = pad + (j / columns) * (cell_h + pad);
    const std::string label = fmt::format("c{}", j + 1);
    canvas.text(x0 + (panel_w - text_width(label, sc)) / 2, y0, label, sc);
    std::vector<std::uint8_t> picture(3 * h * w);
    for (std::size_t p = 0; p < h * w; ++p) {
      const double r = range[j] > 0 ? range[j] : 1.0;
      const Rgb col = !mask[p] ? kMaskColour : nmf ? heat(c[p * k + j] / r) : diverging(0.5 + 0.5 * c[p * k + j] / r);
      std::copy(col.begin(), col.end(), picture.begin() + std::ptrdiff_t(3 * p));
    }
    canvas.blit(x0 + (panel_w - w) / 2, y0 + line, w, h, picture);
    const std::string hi = number_label(range[j]), lo = nmf ? "0" : number_label(-range[j]);
    colour_bar(canvas, x0, y0 + line + h + pad, panel_w, nmf ? std::function<Rgb(double)>(heat) : diverging, "", lo, hi, sc);
  }
  canvas.save_png(path);
}

void run_coefficients(const CoefficientsOptions& o) {
  if (ranks().size() > 1)
    throw UsageError(fmt::format("coefficients writes the store from one process; run it without mpirun ({} ranks)",
                                 ranks().size()));
  const auto start = std::chrono::steady_clock::now();
  const store::Store s = store::Store::open(o.store);
  const store::Basis basis = s.read_basis(o.basis);
  // PCA: the first k components (default all); NMF: all of them.
  const stats::Projector projector(basis, o.k == 0 ? std::nullopt : std::optional<long long>(o.k), o.basis);
  const store::BlockReader reader(s, {.image_globs = o.images});
  projector.check_wavelengths(reader.wavelengths(), s.label() + ": the images", "learn a basis on the images' grid");
  const std::vector<std::string>& images = reader.source_names();
  if (!o.name.empty() && images.size() != 1)
    throw UsageError(fmt::format("--name {} names one map, but {} images match; leave --name out to get <image>.{}",
                                 o.name, images.size(), o.basis));
  std::vector<MapResult> maps(images.size());
  const auto existing = s.coefficients();
  for (std::size_t i = 0; i < images.size(); ++i) {
    maps[i].image = images[i];
    maps[i].name = o.name.empty() ? images[i] + "." + o.basis : o.name;
    store::validate_name(maps[i].name, "coefficient map");
    if (!o.replace && std::find(existing.begin(), existing.end(), maps[i].name) != existing.end())
      throw UsageError(s.label() + ": coefficient map " + maps[i].name + " exists already; pass --replace or choose --name");
  }
  if (!o.plots.empty()) {
    if (fs::exists(o.plots) && !fs::is_directory(o.plots))
      throw UsageError("--plots " + o.plots + ": exists and is not a directory");
  }

  store::StoreWriter writer(o.store, store::WriteOptions{{}, o.replace, command_line()});
  for (MapResult& m : maps) {
    const store::ImageInfo info = s.image_info(m.image);
    m.height = info.height;
    m.width = info.width;
    m.valid = info.valid_pixels;
    store::CoefficientsInfo ci;
    ci.image = m.image;
    ci.basis = o.basis;
    ci.method = basis.method;
    ci.height = info.height;
    ci.width = info.width;
    ci.k = projector.k();
    ci.valid_pixels = info.valid_pixels;
    ci.chunk_rows = std::max<std::size_t>(1, info.chunk_rows);
    ci.provenance = {o.store, basis.method + "-coefficients", command_line(), ""};
    writer.create_coefficients(m.name, ci, projector.basis());
  }

  // Blocks are projected in waves on all threads, then written in block order: the output and the error sums do
  // not depend on the thread count, and memory holds one wave.
  const std::size_t blocks = reader.block_count(), k = projector.k(), bands = reader.bands();
  const std::size_t wave = 4 * std::size_t(std::max(1, omp_get_max_threads()));
  std::vector<store::BlockReader::RawBlock> raw(wave);
  std::vector<std::vector<float>> out(wave);
  std::vector<double> sum_sq(wave);
  std::vector<stats::ProjectionError> errors(wave);
  std::vector<std::uint8_t> ones;
  Progress progress("coefficients on " + o.basis, blocks);
  struct Scratch {
    RowMatrixXd x, coef, recon;
    Eigen::VectorXd e2;
  };
  for (std::size_t first = 0; first < blocks; first += wave) {
    const long long n = static_cast<long long>(std::min(wave, blocks - first));
    parallel_for(std::size_t(n), [] { return Scratch{}; }, [&](std::size_t j, Scratch& t) {
      store::BlockReader::RawBlock& r = raw[j];
      reader.read_raw(first + j, r);
      t.x.resize(Eigen::Index(r.valid), Eigen::Index(bands));
      for (std::size_t p = 0, v = 0; p < r.pixels; ++p)
        if (r.is_valid(p))
          t.x.row(Eigen::Index(v++)) = Eigen::Map<const Eigen::RowVectorXf>(r.spectrum(p, bands), Eigen::Index(bands)).cast<double>();
      t.coef.resize(t.x.rows(), Eigen::Index(k));
      t.recon.resize(t.x.rows(), t.x.cols());
      t.e2.resize(t.x.rows());
      projector.project(t.x, t.coef);
      projector.reconstruct(t.coef, t.recon);
      stats::squared_errors(t.x, t.recon, t.e2);
      errors[j] = {};
      for (Eigen::Index i = 0; i < t.e2.size(); ++i) errors[j].add(t.e2[i]);
      sum_sq[j] = t.x.squaredNorm();
      std::vector<float>& c = out[j];
      c.assign(r.pixels * k, 0.0f);
      for (std::size_t p = 0, v = 0; p < r.pixels; ++p)
        if (r.is_valid(p)) {
          for (std::size_t i = 0; i < k; ++i) c[p * k + i] = float(t.coef(Eigen::Index(v), Eigen::Index(i)));
          ++v;
        }
    });
    for (long long j = 0; j < n; ++j) {
      const std::size_t b = first + std::size_t(j);
      MapResult& m = maps[reader.block_source(b)];
      const store::BlockReader::RawBlock& r = raw[std::size_t(j)];
      std::span<const std::uint8_t> mask(r.mask);
      if (r.mask.empty()) {
        ones.assign(r.pixels, 1);
        mask = ones;
      }
      writer.write_coefficient_rows(m.name, reader.block_first_row(b), r.pixels / m.width, out[std::size_t(j)], mask);
      m.sum_sq += sum_sq[std::size_t(j)];
      m.error.merge(errors[std::size_t(j)]);
    }
    progress.advance(std::uint64_t(n));
  }
  writer.commit();

  if (!o.plots.empty()) {
    fs::create_directories(o.plots);
    const store::Store done = store::Store::open(o.store);
    for (MapResult& m : maps) {
      m.plot = (fs::path(o.plots) / (m.name + ".png")).string();
      write_plot(m.plot, done, m.name);
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto rel = [](const MapResult& m) { return m.sum_sq > 0 ? std::sqrt(m.error.sum_sq / m.sum_sq) : 0.0; };
  auto rms = [&](const MapResult& m) { return m.error.count ? m.error.rms(bands) : 0.0; };
  if (o.json) {
    std::string list;
    for (const MapResult& m : maps)
      list += fmt::format(R"({}{{"name":{},"image":{},"height":{},"width":{},"valid_pixels":{},"rel_error":{},"rms":{},"plot":{}}})",
                          list.empty() ? "" : ",", json_string(m.name), json_string(m.image), m.height, m.width, m.valid,
                          rel(m), rms(m), m.plot.empty() ? "null" : json_string(m.plot));
    fmt::print(R"({{"store":{},"basis":{},"method":{},"k":{},"maps":[{}],"seconds":{}}})" "\n", json_string(o.store),
               json_string(o.basis), json_string(basis.method), k, list, seconds);
    return;
  }
  for (const MapResult& m : maps) {
    fmt::print("{}: {} x {} x {} coefficients in /coefficients/{} (relative error {:.4g}, rms {:.3g})\n", m.image,
               m.height, m.width, k, m.name, rel(m), rms(m));
    if (!m.plot.empty()) fmt::print("wrote {}\n", m.plot);
  }
  fmt::print("{} map(s) on {} ({}, k = {}) in {:.2f} s\n", maps.size(), o.basis, basis.method, k, seconds);
}

}  // namespace

void setup_coefficients(CLI::App& app) {
  auto o = std::make_shared<CoefficientsOptions>();
  auto* cmd = app.add_subcommand(
      "coefficients", "Write the coefficient maps of images on a PCA or NMF basis into the store (chunked), with pictures");
  cmd->add_option("store", o->store, "Store file (the maps are added to it)")->required();
  cmd->add_option("--basis", o->basis, "PCA basis (first k components) or NMF basis (NNLS on all components)")->required();
  cmd->add_option("--images", o->images, "Image name globs (default: every image)");
  cmd->add_option("-k", o->k, "PCA components to keep (default: all the basis has); NMF: must equal the basis's k")
      ->check(CLI::Range(1LL, 100000LL));
  cmd->add_option("--name", o->name, "Name of the map when one image matches (default: <image>.<basis>)");
  cmd->add_option("--plots", o->plots, "Directory for <map>.png: each coefficient as an image with its colour bar");
  cmd->add_flag("--replace", o->replace, "Replace maps of the same names");
  cmd->add_flag("--json", o->json, "Print the result as JSON: maps (name, image, size, rel_error, rms, plot), seconds");
  cmd->footer("rel_error = ||X - X'||_F / ||X||_F over the image's valid pixels, X' reconstructed from the coefficients "
              "(double precision, before they are stored as float32); rms = sqrt(mean squared error per band).");
  cmd->callback([o] { run_coefficients(*o); });
}

}  // namespace specula::app
