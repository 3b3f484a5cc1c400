// specula relight (reference §4.1.7): an image taken under one light shown under another, relit spectrally
// (eq 4.9: divide out the old light per wavelength, multiply in the new) and as an RGB camera would
// (eq 4.10: per-channel von Kries scaling), side by side, with the CIEDE2000 difference between the two.
#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct RelightOptions {
  std::string store;
  std::string image;
  std::string from = "D65";
  std::string to = "A";
  std::string output;
  PreviewOptions preview;
  bool json = false;
};


void run_relight(const RelightOptions& o) {
  const store::Store s = store::Store::open(o.store);
  const store::Cube cube = s.read_image(o.image);
  const WavelengthGrid& grid = cube.wavelengths;
  const Eigen::VectorXd l_from = load_illuminant(o.from, grid);
  const Eigen::VectorXd l_to = load_illuminant(o.to, grid);
  const bool reflectance = cube.units == "reflectance";
  for (Eigen::Index b = 0; b < l_from.size(); ++b)
    if (!reflectance && !(l_from[b] > 0))
      throw InputError(fmt::format("illuminant {} is zero at {} nm, so it cannot be divided out of {}", o.from,
                                   grid[std::size_t(b)], o.image));

  const Eigen::Index n = Eigen::Index(cube.height * cube.width), nb = Eigen::Index(cube.bands);
  const Eigen::Map<const RowMatrixXf> data(cube.data.data(), n, nb);
  // Reflectance f: the data itself, or the radiance with the old light divided out (eq 4.9).
  RowMatrixXf f = reflectance ? RowMatrixXf(data) : RowMatrixXf(data.array().rowwise() / l_from.transpose().cast<float>().array());

  const SpectrumToXyz under_from(grid, SpectrumKind::reflectance, l_from);
  const SpectrumToXyz under_to(grid, SpectrumKind::reflectance, l_to);
  RowMatrixX3f xyz_orig(n, 3), xyz_spec(n, 3);
  under_from.apply(f, xyz_orig);
  if (!reflectance) {
    // Radiance has no absolute scale: call the 99th-percentile luminance under the old light white (Y = 1),
    // so the colour differences below do not depend on the data's units.
    std::vector<float> y = valid_luminance(xyz_orig, cube);
    const double white = quantile(y, 0.99);
    if (white > 0) {
      f /= float(white);
      xyz_orig /= float(white);
    }
  }
  under_to.apply(f, xyz_spec);

  // RGB camera: linear-sRGB matching curves M * cmf; per-channel scaling by the lights' responses (eq 4.10).
  const Eigen::Matrix3d m = xyz_to_linear_srgb();
  const Eigen::Matrix<double, 3, Eigen::Dynamic> camera = m * SpectrumToXyz(grid, SpectrumKind::radiance, l_to).weights();
  const Eigen::Vector3d resp_from = camera * l_from, resp_to = camera * l_to;
  const double y_to = (SpectrumToXyz(grid, SpectrumKind::radiance, l_to).weights() * l_to)(1);
  const Eigen::Matrix3d rgb_to_xyz = m.inverse();
  const Eigen::Vector3d gain = resp_to.cwiseQuotient(resp_from) / y_to;
  RowMatrixX3f xyz_rgb(n, 3);
  const Eigen::Matrix3f to_xyz = (rgb_to_xyz * gain.asDiagonal()).cast<float>();
  const Eigen::Matrix<float, 3, Eigen::Dynamic> cam_f = camera.cast<float>();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3f captured = cam_f * (f.row(i).transpose().array() * l_from.cast<float>().array()).matrix();
    xyz_rgb.row(i) = (to_xyz * captured).transpose();
  }

  // CIEDE2000 between the two relit images, relative to the new light's white.
  const Eigen::Vector3d white_to = under_to.white();
  std::vector<double> de;
  std::vector<double> de_map(std::size_t(n), 0.0);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!cube.valid(std::size_t(i) / cube.width, std::size_t(i) % cube.width)) continue;
    const double d = ciede2000(xyz_to_lab(xyz_spec.row(i).transpose().cast<double>(), white_to),
                               xyz_to_lab(xyz_rgb.row(i).transpose().cast<double>(), white_to));
    de.push_back(d);
    de_map[std::size_t(i)] = d;
  }
  if (de.empty()) throw InputError(s.label() + ": image '" + o.image + "' has no valid pixels");
  double mean = 0;
  for (double d : de) mean += d;
  mean /= double(de.size());
  std::vector<double> sorted = de;
  std::sort(sorted.begin(), sorted.end());
  const double p95 = sorted[std::size_t(0.95 * double(sorted.size() - 1))], mx = sorted.back();

  // Panels: original | spectral relighting | RGB relighting | CIEDE2000 map (0 to 10).
  DisplayOptions d;
  d.tone = o.preview.tone == "reinhard" ? ToneMap::reinhard : ToneMap::clip;
  d.desaturate = !o.preview.no_desaturate;
  d.adapt_to_d65 = !o.preview.no_adapt;
  if (const auto stops = parse_exposure(o.preview.exposure)) {
    d.exposure_stops = *stops;
  } else {
    std::vector<float> y = valid_luminance(xyz_orig.cwiseMax(xyz_spec), cube);
    const double white = quantile(y, 0.99);
    d.exposure_stops = white > 0 ? -std::log2(white) : 0.0;
  }
  const std::size_t w = cube.width, h = cube.height, gap = 4, panels = 4;
  const std::size_t pw = panels * w + (panels - 1) * gap;
  std::vector<std::uint8_t> out(3 * pw * h, 255);
  RowMatrixX3f lin(n, 3);
  std::vector<std::uint8_t> tmp(3 * std::size_t(n));
  const RowMatrixX3f* sources[3] = {&xyz_orig, &xyz_spec, &xyz_rgb};
  const Eigen::Vector3d whites[3] = {under_from.white(), white_to, white_to};
  for (std::size_t p = 0; p < 3; ++p) {
    xyz_to_display(*sources[p], whites[p], d, lin, tmp);
    for (std::size_t y = 0; y < h; ++y)
      std::copy_n(tmp.begin() + std::ptrdiff_t(3 * y * w), 3 * w, out.begin() + std::ptrdiff_t(3 * (y * pw + p * (w + gap))));
  }
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x) {
      const auto c = heat(de_map[y * w + x] / 10.0);
      std::copy(c.begin(), c.end(), out.begin() + std::ptrdiff_t(3 * (y * pw + 3 * (w + gap) + x)));
    }
  store::write_png_rgb8(o.output, pw, h, out);
  if (o.json) {
    fmt::print(R"({{"image":{},"from":{},"to":{},"pixels":{},"mean_ciede2000":{},"p95_ciede2000":{},"max_ciede2000":{},"output":{}}})"
               "\n",
               json_string(o.image), json_string(o.from), json_string(o.to), de.size(), mean, p95, mx, json_string(o.output));
  } else {
    fmt::print("{}: relit from {} to {}: mean CIEDE2000 between spectral and RGB relighting {:.3f} "
               "(95th percentile {:.3f}, max {:.3f}) over {} pixels\n",
               o.image, o.from, o.to, mean, p95, mx, de.size());
    fmt::print("wrote {} (panels: under {}, spectral relighting to {}, RGB relighting to {}, CIEDE2000 map 0-10)\n",
               o.output, o.from, o.to, o.to);
  }
}

}  // namespace

void setup_relight(CLI::App& app) {
  auto o = std::make_shared<RelightOptions>();
  auto* cmd = app.add_subcommand("relight", "Relight an image spectrally (eq 4.9) and in RGB (eq 4.10); compare with CIEDE2000");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("image", o->image, "Image name")->required();
  cmd->add_option("--from", o->from,
                  "Light the image was taken under (radiance data, whose 99th-percentile luminance is taken as white) "
                  "or shown under (reflectance)")
      ->capture_default_str();
  cmd->add_option("--to", o->to, "New light")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "PNG with the panels side by side")->required();
  cmd->add_flag("--json", o->json, "Print the result as JSON");
  add_preview_options(cmd, o->preview, /*with_illuminant=*/false);
  cmd->callback([o] { run_relight(*o); });
}

}  // namespace specula::app
