// specula acquire STEP: the pipeline from a capture directory (docs/capture-format.md) to scattered BRDF samples,
// one subcommand per step, each recording its result in a store. Steps so far: hdr.
#include <fmt/format.h>

#include <array>
#include <chrono>
#include <filesystem>

#include "acquire/capture.h"
#include "acquire/hdr.h"
#include "apps/commands.h"
#include "apps/common.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/progress.h"
#include "store/io/png_stack.h"
#include "store/store.h"

namespace specula::app {
namespace {

struct AcquireHdrOptions {
  std::string capture;
  std::string output;
  double low = 15.0 / 255, high = 240.0 / 255, min_pearson = 0.99;
  bool replace = false;
  bool json = false;
};

constexpr std::array<const char*, 5> kStatusNames = {"ok", "single", "saturated", "low_signal", "nonlinear"};

// Merges every light's exposure series into one image per light position, "hdr-L<index>": rates (DN/s) in every
// band; a pixel is valid when every band has a value in the linear range (ok or single).
void run_acquire_hdr(const AcquireHdrOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const acquire::Capture cap = acquire::read_manifest(o.capture);
  const acquire::HdrOptions ho{o.low, o.high, o.min_pearson};
  const std::size_t W = std::size_t(cap.width), H = std::size_t(cap.height), B = cap.bands.size(), lights = cap.light_angles_deg.size();
  std::vector<std::vector<std::vector<const acquire::CaptureImage*>>> series(lights, std::vector<std::vector<const acquire::CaptureImage*>>(B));
  for (const auto& im : cap.images)
    if (im.kind == acquire::ImageKind::scene) series[std::size_t(im.light)][std::size_t(im.band)].push_back(&im);
  store::StoreWriter writer(o.output, {.replace = o.replace, .command_line = command_line()});
  std::array<std::uint64_t, 5> counts{};
  std::uint64_t valid = 0;
  Progress progress("hdr", lights);
  for (std::size_t l = 0; l < lights; ++l) {
    check_interrupt();
    store::Cube cube;
    cube.resize(H, W, B);
    cube.wavelengths = WavelengthGrid(cap.bands);
    cube.units = "DN/s";
    cube.provenance.source_file = o.capture;
    cube.provenance.importer = "acquire-hdr";
    cube.mask.assign(H * W, 1);
    for (std::size_t b = 0; b < B; ++b) {
      std::vector<std::vector<std::uint16_t>> pixels;
      std::vector<double> times;
      for (const auto* im : series[l][b]) {
        const std::filesystem::path file = std::filesystem::path(o.capture) / im->file;
        const store::PngImage png = store::read_png(file);
        if (png.width != W || png.height != H || png.channels != 1)
          throw InputError(file.string() + ": " + std::to_string(png.width) + " x " + std::to_string(png.height) + " x " +
                           std::to_string(png.channels) + " channels; the manifest says grey " + std::to_string(W) + " x " + std::to_string(H));
        pixels.push_back(png.samples);
        times.push_back(im->exposure_s);
      }
      std::vector<std::span<const std::uint16_t>> views(pixels.begin(), pixels.end());
      const acquire::HdrImage hdr = acquire::merge_exposures(views, times, cap.bit_depth, ho);
      for (std::size_t p = 0; p < H * W; ++p) {
        cube.data[p * B + b] = hdr.rate[p];
        ++counts[std::size_t(hdr.status[p])];
        if (hdr.status[p] != acquire::HdrStatus::ok && hdr.status[p] != acquire::HdrStatus::single) cube.mask[p] = 0;
      }
    }
    for (const auto m : cube.mask) valid += m;
    writer.add_image(fmt::format("hdr-L{:03}", l), cube);
    progress.advance();
  }
  writer.commit();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    std::string by;
    for (std::size_t s = 0; s < counts.size(); ++s) by += fmt::format("{}\"{}\":{}", s ? "," : "", kStatusNames[s], counts[s]);
    fmt::print("{{\"lights\":{},\"bands\":{},\"pixels\":{},\"valid_pixels\":{},\"status\":{{{}}},\"seconds\":{:.3f}}}\n", lights, B,
               W * H * lights, valid, by, seconds);
    return;
  }
  fmt::print("merged {} light positions x {} bands into {} ({} of {} pixels valid in every band) in {:.1f} s\n", lights, B, o.output,
             valid, W * H * lights, seconds);
  for (std::size_t s = 0; s < counts.size(); ++s) fmt::print("  {:<11} {}\n", kStatusNames[s], counts[s]);
}

}  // namespace

void setup_acquire(CLI::App& app) {
  auto* cmd = app.add_subcommand("acquire", "From a capture directory to BRDF samples, step by step");
  cmd->require_subcommand(1);
  auto o = std::make_shared<AcquireHdrOptions>();
  auto* hdr = cmd->add_subcommand("hdr", "Merge each light's exposures into HDR images (slope of value against time)");
  hdr->add_option("capture", o->capture, "Capture directory (manifest.json)")->required();
  hdr->add_option("-o,--output", o->output, "Store (.h5) to add hdr-L<index> images to")->required();
  hdr->add_option("--low", o->low, "Lowest value in the linear range (fraction of full scale)")->capture_default_str();
  hdr->add_option("--high", o->high, "Highest value in the linear range (fraction of full scale)")->capture_default_str();
  hdr->add_option("--min-pearson", o->min_pearson, "Fits with a lower Pearson r are flagged non-linear")->capture_default_str();
  hdr->add_flag("--replace", o->replace, "Replace images of the same names");
  hdr->add_flag("--json", o->json, "Print one JSON object");
  hdr->callback([o] { run_acquire_hdr(*o); });
}

}  // namespace specula::app
