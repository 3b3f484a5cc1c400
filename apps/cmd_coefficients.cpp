// specula coefficients: coefficient maps of chosen images on a PCA basis (eq 7.2) or an NMF basis (exact NNLS),
// streamed block by block from the store into chunked /coefficients/<name> datasets, with pictures of the maps.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/stats/coefficients.h"
#include "specula/stats/figures.h"
#include "specula/stats/project.h"
#include "specula/store/block_reader.h"
#include "specula/store/io/png_stack.h"
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

// One figure per map: its k coefficient images side by side with their colour bars (stats::coefficient_figure).
void write_plot(const fs::path& path, const store::Store& s, const std::string& name) {
  const store::CoefficientsInfo info = s.coefficients_info(name);
  std::vector<float> c(info.height * info.width * info.k);
  std::vector<std::uint8_t> mask(info.height * info.width);
  s.read_coefficient_rows(name, 0, info.height, c, mask);
  const Canvas canvas = stats::coefficient_figure(info.height, info.width, info.k, c, mask, info.method == "nmf");
  store::write_png_rgb8(path, canvas.width, canvas.height, canvas.rgb);
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
  const std::vector<std::string>& images = reader.source_names();
  if (!o.name.empty() && images.size() != 1)
    throw UsageError(fmt::format("--name {} names one map, but {} images match; leave --name out to get <image>.{}",
                                 o.name, images.size(), o.basis));
  std::vector<std::string> names(images.size());
  const auto existing = s.coefficients();
  for (std::size_t i = 0; i < images.size(); ++i) {
    names[i] = o.name.empty() ? images[i] + "." + o.basis : o.name;
    store::validate_name(names[i], "coefficient map");
    if (!o.replace && std::find(existing.begin(), existing.end(), names[i]) != existing.end())
      throw UsageError(s.label() + ": coefficient map " + names[i] +
                       " exists already; pass --replace or choose --name");
  }
  if (!o.plots.empty()) {
    if (fs::exists(o.plots) && !fs::is_directory(o.plots))
      throw UsageError("--plots " + o.plots + ": exists and is not a directory");
  }

  store::StoreWriter writer(o.store, store::WriteOptions{{}, o.replace, command_line()});
  const std::vector<stats::CoefficientMap> maps = stats::write_coefficient_maps(
      s, reader, projector, names,
      {.basis_name = o.basis, .provenance = {o.store, basis.method + "-coefficients", command_line(), ""}}, writer);
  writer.commit();

  std::vector<std::string> plots(maps.size());
  if (!o.plots.empty()) {
    fs::create_directories(o.plots);
    const store::Store done = store::Store::open(o.store);
    for (std::size_t i = 0; i < maps.size(); ++i) {
      plots[i] = (fs::path(o.plots) / (maps[i].name + ".png")).string();
      write_plot(plots[i], done, maps[i].name);
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::size_t k = projector.k(), bands = projector.bands();
  auto rms = [&](const stats::CoefficientMap& m) { return m.error.count ? m.error.rms(bands) : 0.0; };
  if (o.json) {
    Json list = Json::array();
    for (std::size_t i = 0; i < maps.size(); ++i) {
      const stats::CoefficientMap& m = maps[i];
      list.push_back({{"name", m.name},
                      {"image", m.image},
                      {"height", m.height},
                      {"width", m.width},
                      {"valid_pixels", m.valid},
                      {"rel_error", m.relative_error()},
                      {"rms", rms(m)},
                      {"plot", plots[i].empty() ? Json() : Json(plots[i])}});
    }
    Json j;
    j["store"] = o.store;
    j["basis"] = o.basis;
    j["method"] = basis.method;
    j["k"] = k;
    j["maps"] = std::move(list);
    j["seconds"] = seconds;
    print_json(j);
    return;
  }
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const stats::CoefficientMap& m = maps[i];
    fmt::print("{}: {} x {} x {} coefficients in /coefficients/{} (relative error {:.4g}, rms {:.3g})\n", m.image,
               m.height, m.width, k, m.name, m.relative_error(), rms(m));
    if (!plots[i].empty()) fmt::print("wrote {}\n", plots[i]);
  }
  fmt::print("{} map(s) on {} ({}, k = {}) in {:.2f} s\n", maps.size(), o.basis, basis.method, k, seconds);
}

}  // namespace

void setup_coefficients(CLI::App& app) {
  auto o = std::make_shared<CoefficientsOptions>();
  auto* cmd = app.add_subcommand(
      "coefficients",
      "Write the coefficient maps of images on a PCA or NMF basis into the store (chunked), with pictures");
  cmd->add_option("store", o->store, "Store file (the maps are added to it)")->required();
  cmd->add_option("--basis", o->basis, "PCA basis (first k components) or NMF basis (NNLS on all components)")
      ->required();
  cmd->add_option("--images", o->images, "Image name globs (default: every image)");
  cmd->add_option("-k", o->k, "PCA components to keep (default: all the basis has); NMF: must equal the basis's k")
      ->check(CLI::Range(1LL, 100000LL));
  cmd->add_option("--name", o->name, "Name of the map when one image matches (default: <image>.<basis>)");
  cmd->add_option("--plots", o->plots, "Directory for <map>.png: each coefficient as an image with its colour bar");
  cmd->add_flag("--replace", o->replace, "Replace maps of the same names");
  cmd->add_flag("--json", o->json, "Print the result as JSON: maps (name, image, size, rel_error, rms, plot), seconds");
  cmd->footer(
      "rel_error = ||X - X'||_F / ||X||_F over the image's valid pixels, X' reconstructed from the coefficients "
      "(double precision, before they are stored as float32); rms = sqrt(mean squared error per band).");
  cmd->callback([o] { run_coefficients(*o); });
}

}  // namespace specula::app
