// specula project (reference §7.3, eqs 7.2-7.3, figure 7.4; §7.4, figure 7.7): an image projected onto the
// first k principal components of a PCA basis, or by non-negative least squares onto an NMF basis, and
// reconstructed, with the per-pixel error of each reconstruction.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/canvas.h"
#include "specula/core/error.h"
#include "specula/stats/figures.h"
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

struct KResult {
  std::size_t k = 0;
  double rms = 0, max_error = 0;
  std::vector<float> error;           // per-pixel L2 error over bands
  std::vector<std::uint8_t> preview;  // sRGB8 of the reconstruction
};

void write_canvas(const fs::path& path, const Canvas& c) { store::write_png_rgb8(path, c.width, c.height, c.rgb); }

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

// The folder -o names (or the folder of the .exr it names), created.
void make_output_folder(const std::string& output) {
  if (!names_exr(output)) {
    if (fs::exists(output) && !fs::is_directory(output))
      throw UsageError("-o " + output + ": exists and is not a directory; give a directory or a .exr file");
    fs::create_directories(output);
  } else if (const fs::path parent = fs::path(output).parent_path(); !parent.empty()) {
    fs::create_directories(parent);
  }
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
  make_output_folder(o.output);

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
    write_canvas(p.error, stats::error_figure(cube.width, cube.height, r.error, cube.mask, r.max_error));
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
    std::vector<stats::PanelColumn> columns;
    for (const KResult& r : results) columns.push_back({r.k, r.rms, r.max_error, r.error, r.preview});
    write_canvas(panel,
                 stats::projection_panel(cube.width, cube.height, render(cube, preview).srgb8, cube.mask, columns));
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
