// specula synth-db: a realistic synthetic database of hyperspectral radiance images (store/synth.h), so
// benchmarks and the demo reach the reference's 59 million spectra without outside data. Ctrl-C keeps the
// images already finished.
#include <fmt/format.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/progress.h"
#include "specula/store/store.h"
#include "specula/store/synth.h"

namespace specula::app {
namespace {

struct SynthDbOptions {
  std::string output;
  std::size_t images = 4;
  std::string size = "256x256";
  std::uint64_t seed = 1;
  std::string wavelengths = "420:720:10";
  double noise = 0.01;
  std::string compression = "deflate";
  std::string prefix = "synth";
  bool replace = false;
};

std::pair<std::size_t, std::size_t> parse_size(const std::string& s) {
  const auto x = s.find('x');
  try {
    std::size_t p1 = 0, p2 = 0;
    const unsigned long h = std::stoul(s.substr(0, x), &p1), w = std::stoul(s.substr(x + 1), &p2);
    if (x != std::string::npos && p1 == x && p2 == s.size() - x - 1 && h > 0 && w > 0 && h <= 65536 && w <= 65536)
      return {h, w};
  } catch (...) {}
  throw UsageError("--size '" + s + "': use HEIGHTxWIDTH with each 1-65536, e.g. 1040x1392");
}

void run_synth_db(const SynthDbOptions& o) {
  store::SynthOptions so;
  std::tie(so.height, so.width) = parse_size(o.size);
  so.images = o.images;
  so.seed = o.seed;
  so.wavelengths = WavelengthGrid::parse(o.wavelengths);
  so.noise = o.noise;
  if (o.images == 0 || o.images > 100000) throw UsageError("--images must be 1-100000");
  if (!(o.noise >= 0 && o.noise <= 1)) throw UsageError("--noise must be between 0 and 1");
  store::validate_name(o.prefix, "--prefix");
  const auto digits = std::to_string(o.images - 1).size();
  store::StoreWriter writer(
      o.output,
      {.compression = store::Compression::parse(o.compression), .replace = o.replace, .command_line = command_line()});
  Progress bar("synth-db", o.images);
  set_progress_quiet(true);  // one bar for the whole database, none per image
  std::size_t done = 0;
  std::uint64_t spectra = 0;
  try {
    for (std::size_t i = 0; i < o.images; ++i) {
      check_interrupt();
      store::Cube cube = store::synthesize_image(so, i);
      cube.provenance.importer = "synth-db";
      cube.provenance.source_file = fmt::format("synth-db seed {} image {}", o.seed, i);
      writer.add_image(fmt::format("{}{:0{}}", o.prefix, i, digits), cube);
      spectra += cube.mask.empty() ? cube.height * cube.width
                                   : std::uint64_t(std::count(cube.mask.begin(), cube.mask.end(), 1));
      ++done;
      bar.advance();
    }
  } catch (const Interrupted&) {
    if (done > 0) {
      writer.commit();
      fmt::print(stderr, "synth-db: interrupted after {} of {} images; {} holds the {} finished\n", done, o.images,
                 o.output, done);
    }
    throw;
  }
  writer.commit();
  fmt::print("wrote {}: {} images {}x{}, {}, {} valid spectra\n", o.output, o.images, so.height, so.width,
             so.wavelengths.describe(), spectra);
}

}  // namespace

void setup_synth_db(CLI::App& app) {
  auto o = std::make_shared<SynthDbOptions>();
  auto* cmd =
      app.add_subcommand("synth-db", "Write a synthetic database of natural-looking hyperspectral radiance images");
  cmd->add_option("-o,--output", o->output, "Store to create or add to")->required();
  cmd->add_option("--images", o->images, "Number of images")->capture_default_str();
  cmd->add_option("--size", o->size, "HEIGHTxWIDTH of each image")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed (same seed, same database)")->capture_default_str();
  cmd->add_option("--wavelengths", o->wavelengths, "Band grid FIRST:LAST:STEP")->capture_default_str();
  cmd->add_option("--noise", o->noise, "Sensor read noise relative to the mean radiance")->capture_default_str();
  cmd->add_option("--compression", o->compression, "none, deflate or deflate:LEVEL")->capture_default_str();
  cmd->add_option("--prefix", o->prefix, "Image names are PREFIX0, PREFIX1, ...")->capture_default_str();
  cmd->add_flag("--replace", o->replace, "Replace images of the same name");
  cmd->callback([o] { run_synth_db(*o); });
}

}  // namespace specula::app
