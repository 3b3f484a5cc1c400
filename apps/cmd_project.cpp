// specula project (reference §7.3, eqs 7.2-7.3, figure 7.4; §7.4, figure 7.7): an image projected onto the
// first k principal components of a PCA basis, or by non-negative least squares onto an NMF basis, and
// reconstructed, with the per-pixel error of each reconstruction.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "apps/canvas.h"
#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/stats/project.h"
#include "specula/store/io/exr.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

namespace fs = std::filesystem;

constexpr const char* kRmsDefinition = stats::kProjectionErrorDefinition;

struct ProjectOptions {
  std::string store;
  std::string basis;
  std::vector<long long> ks;
  std::string image;
  std::string output;
  std::string into_store;
  PreviewOptions preview;
  bool json = false;
};

// A horizontal colour bar of the error ramp from 0 to max_value at (x, y), labelled under its ends.
void error_bar(Canvas& c, std::size_t x, std::size_t y, std::size_t w, double max_value, std::size_t s) {
  colour_bar(c, x, y, w, heat, "L2 error", "0", number_label(max_value), s);
}

std::size_t error_bar_min_width(double max_value, std::size_t s) {
  return bar_min_width("L2 error", "0", number_label(max_value), s);
}

std::vector<std::uint8_t> error_rgb(const std::vector<float>& err, const Cube& cube, double max_value) {
  std::vector<std::uint8_t> out(3 * err.size());
  for (std::size_t i = 0; i < err.size(); ++i) {
    const Rgb c = !cube.mask.empty() && !cube.mask[i] ? kMaskColour : heat(max_value > 0 ? err[i] / max_value : 0.0);
    std::copy(c.begin(), c.end(), out.begin() + std::ptrdiff_t(3 * i));
  }
  return out;
}

// The error map of one reconstruction above its colour bar (0 to the largest valid error).
void write_error_png(const fs::path& path, const std::vector<float>& err, const Cube& cube, double max_value) {
  const std::size_t s = font_scale(cube.width), pad = 4 * s;
  const std::size_t inner = std::max(cube.width, error_bar_min_width(max_value, s));
  Canvas c(inner + 2 * pad, pad + cube.height + pad + bar_height(s) + pad);
  c.blit(pad + (inner - cube.width) / 2, pad, cube.width, cube.height, error_rgb(err, cube, max_value));
  error_bar(c, pad, pad + cube.height + pad, inner, max_value, s);
  store::write_png_rgb8(path, c.width, c.height, c.rgb);
}

struct KResult {
  std::size_t k = 0;
  double rms = 0, max_error = 0;
  std::vector<float> error;           // per-pixel L2 error over bands
  std::vector<std::uint8_t> preview;  // sRGB8 of the reconstruction
};

// Figure 7.4: the original and each reconstruction on top, their error maps (one shared scale) below.
void write_panel(const fs::path& path, const Cube& cube, const std::vector<std::uint8_t>& original,
                 const std::vector<KResult>& results) {
  const std::size_t w = cube.width, h = cube.height, n = results.size();
  const std::size_t s = font_scale(w), pad = 4 * s, line = 7 * s + 3 * s;
  double shared = 0;
  for (const KResult& r : results) shared = std::max(shared, r.max_error);
  std::vector<std::string> rms_labels;
  std::size_t col = std::max(w, text_width("original", s));
  for (const KResult& r : results) {
    rms_labels.push_back("rms " + number_label(r.rms));
    col = std::max({col, text_width(rms_labels.back(), s), text_width(fmt::format("k={}", r.k), s)});
  }
  const std::size_t bar_w_min = error_bar_min_width(shared, s);
  if (n * col + (n - 1) * pad < bar_w_min) col = (bar_w_min - (n - 1) * pad + n - 1) / n;
  const std::size_t top = pad + line, bottom = top + h + pad;
  const std::size_t bar_y = bottom + h + s + line + pad;
  Canvas c(pad + (n + 1) * col + n * pad + pad, bar_y + bar_height(s) + pad);
  auto column_x = [&](std::size_t i) { return pad + i * (col + pad); };
  auto centred = [&](std::size_t i, std::size_t width) { return column_x(i) + (col - width) / 2; };
  c.text(centred(0, text_width("original", s)), pad, "original", s);
  c.blit(centred(0, w), top, w, h, original);
  for (std::size_t i = 0; i < n; ++i) {
    const std::string label = fmt::format("k={}", results[i].k);
    c.text(centred(i + 1, text_width(label, s)), pad, label, s);
    c.blit(centred(i + 1, w), top, w, h, results[i].preview);
    c.blit(centred(i + 1, w), bottom, w, h, error_rgb(results[i].error, cube, shared));
    c.text(centred(i + 1, text_width(rms_labels[i], s)), bottom + h + 2 * s, rms_labels[i], s);
  }
  error_bar(c, column_x(1), bar_y, n * col + (n - 1) * pad, shared, s);
  store::write_png_rgb8(path, c.width, c.height, c.rgb);
}

// The original's settings with its automatic exposure fixed, so every reconstruction is shown alike.
PreviewSettings shared_settings(const Cube& cube, const PreviewOptions& o) {
  PreviewSettings p = preview_settings(o, cube.wavelengths);
  if (!p.exposure_stops) {
    Eigen::Vector3d white;
    const RowMatrixX3f xyz = spectra_to_xyz(cube_rows(cube), cube.wavelengths, cube_kind(cube), p.illuminant, white);
    p.exposure_stops = auto_exposure_stops(xyz, cube.mask, cube_kind(cube));
  }
  return p;
}

struct OutputPaths {
  fs::path reconstruction, preview, error;
};

bool names_exr(const std::string& out) {
  std::string ext = fs::path(out).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  return ext == ".exr";
}

OutputPaths paths_for(const ProjectOptions& o, std::size_t k) {
  if (names_exr(o.output)) {
    const fs::path out = o.output;
    const fs::path stem = out.parent_path() / out.stem();
    return {out, stem.string() + "-preview.png", stem.string() + "-error.png"};
  }
  const fs::path dir = o.output;
  return {dir / fmt::format("reconstruction-k{}.exr", k), dir / fmt::format("preview-k{}.png", k),
          dir / fmt::format("error-k{}.png", k)};
}

void run_project(const ProjectOptions& o) {
  std::vector<std::size_t> ks;
  store::Basis basis;
  Cube cube;
  {
    const store::Store s = store::Store::open(o.store);
    basis = s.read_basis(o.basis);
    if (stats::basis_method(basis, o.basis) == stats::BasisMethod::pca && o.ks.empty())
      throw UsageError("-k is required with a PCA basis (e.g. -k 6, or -k 1,3,6,31 for figure 7.4's panel)");
    // One projector per k checks k (an NMF basis projects onto all of its components, so at most one k).
    for (long long k : o.ks) ks.push_back(stats::Projector(basis, k, o.basis).k());
    if (ks.empty()) ks.push_back(basis.k());
    std::sort(ks.begin(), ks.end());
    ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
    if (ks.size() > 1 && names_exr(o.output))
      throw UsageError("-o " + o.output + " names one reconstruction; with several -k give a directory");
    const store::ImageInfo info = s.image_info(o.image);
    stats::Projector(basis, std::nullopt, o.basis)
        .check_wavelengths(
            info.wavelengths, s.label() + ": image " + o.image,
            "import the image with --wavelengths to match the basis, or learn a basis on the image's grid");
    if (info.valid_pixels == 0) throw InputError(s.label() + ": image " + o.image + " has no valid pixels");
    if (!o.into_store.empty()) {
      const auto images = s.images();
      for (std::size_t k : ks) {
        const std::string name = fmt::format("{}-k{}", o.into_store, k);
        store::validate_name(name, "image");
        if (std::find(images.begin(), images.end(), name) != images.end())
          throw UsageError(s.label() + ": image " + name + " already exists; choose another --into-store name");
      }
    }
    cube = s.read_image(o.image);
  }
  if (!names_exr(o.output)) {
    if (fs::exists(o.output) && !fs::is_directory(o.output))
      throw UsageError("-o " + o.output + ": exists and is not a directory; give a directory or a .exr file");
    fs::create_directories(o.output);
  } else if (const fs::path parent = fs::path(o.output).parent_path(); !parent.empty()) {
    fs::create_directories(parent);
  }

  const PreviewSettings preview = shared_settings(cube, o.preview);
  std::unique_ptr<store::StoreWriter> writer;
  if (!o.into_store.empty())
    writer = std::make_unique<store::StoreWriter>(o.store, store::WriteOptions{{}, false, command_line()});
  Cube recon;
  recon.height = cube.height;
  recon.width = cube.width;
  recon.bands = cube.bands;
  recon.mask = cube.mask;
  recon.wavelengths = cube.wavelengths;
  recon.fwhm = cube.fwhm;
  recon.units = cube.units;
  recon.provenance = {o.store, basis.method + "-project", command_line(), ""};

  std::vector<KResult> results;
  std::vector<std::string> outputs, store_images;
  for (std::size_t k : ks) {
    recon.data.resize(cube.data.size());
    stats::ImageProjection proj =
        stats::project_image(cube, stats::Projector(basis, static_cast<long long>(k), o.basis), recon.data);
    KResult r{.k = proj.k, .rms = proj.rms, .max_error = proj.max_error, .error = std::move(proj.error), .preview = {}};
    const OutputPaths p = paths_for(o, k);
    store::write_spectral_exr(p.reconstruction, recon);
    r.preview = render(recon, preview).srgb8;
    store::write_png_rgb8(p.preview, recon.width, recon.height, r.preview);
    write_error_png(p.error, r.error, cube, r.max_error);
    for (const fs::path& f : {p.reconstruction, p.preview, p.error}) outputs.push_back(f.string());
    if (writer) {
      store_images.push_back(fmt::format("{}-k{}", o.into_store, k));
      writer->add_image(store_images.back(), recon);
    }
    if (ks.size() == 1) r.error.clear();
    results.push_back(std::move(r));
  }
  if (ks.size() > 1) {
    const fs::path panel = fs::path(o.output) / "panel.png";
    write_panel(panel, cube, render(cube, preview).srgb8, results);
    outputs.push_back(panel.string());
  }
  if (writer) writer->commit();

  if (o.json) {
    Json res = Json::array();
    for (const KResult& r : results) res.push_back({{"k", r.k}, {"rms", r.rms}, {"max_error", r.max_error}});
    Json j;
    j["image"] = o.image;
    j["basis"] = o.basis;
    j["rms_definition"] = kRmsDefinition;
    j["results"] = std::move(res);
    j["outputs"] = outputs;
    j["store_images"] = store_images;
    print_json(j);
    return;
  }
  for (const KResult& r : results)
    fmt::print("k={}: rms {:.3g}, max {:.3g} (L2 over bands)\n", r.k, r.rms, r.max_error);
  for (const std::string& f : outputs) fmt::print("wrote {}\n", f);
  for (const std::string& n : store_images) fmt::print("added image {} to {}\n", n, o.store);
}

}  // namespace

void setup_project(CLI::App& app) {
  auto o = std::make_shared<ProjectOptions>();
  auto* cmd = app.add_subcommand(
      "project",
      "Reconstruct an image from k principal components (figure 7.4) or an NMF basis (figure 7.7), with error maps");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("--basis", o->basis,
                  "PCA or NMF basis in the store (NMF: non-negative least squares on all its components)")
      ->required();
  cmd->add_option("-k", o->ks, "PCA components to keep, e.g. 3 or 1,3,6,31 (several also write panel.png)")
      ->delimiter(',');
  cmd->add_option("--image", o->image, "Image in the store, on the basis's wavelength grid")->required();
  cmd->add_option("-o,--output", o->output,
                  "Directory for reconstruction-k<K>.exr, preview-k<K>.png, error-k<K>.png (and panel.png); "
                  "with one k, a .exr file for the reconstruction (previews beside it)")
      ->required();
  cmd->add_option("--into-store", o->into_store, "Also add the reconstructions to the store as images NAME-k<K>");
  cmd->add_flag("--json", o->json, std::string("Print the result as JSON; ") + kRmsDefinition);
  add_preview_options(cmd, o->preview);
  cmd->footer(std::string("Errors: ") + kRmsDefinition + "; masked pixels are left out.");
  cmd->callback([o] { run_project(*o); });
}

}  // namespace specula::app
