// specula info and specula ls: what a store holds, for people (text) and programs (--json).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/info_json.h"
#include "specula/acquire/pipeline.h"
#include "specula/core/error.h"
#include "specula/store/info_json.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct InfoOptions {
  std::string store;
  std::string object;
  bool json = false;
};

std::string image_line(const store::ImageInfo& i) {
  return fmt::format("image       {:<24} {}x{}  {}  {} valid  {}  [{}]", i.name, i.height, i.width,
                     i.wavelengths.describe(), i.valid_pixels, i.units, i.compression);
}
std::string collection_line(const store::CollectionInfo& c) {
  return fmt::format("collection  {:<24} {} spectra  {}  {}", c.name, c.size, c.wavelengths.describe(), c.units);
}
std::string samples_line(const store::SamplesInfo& s) {
  return fmt::format("samples     {:<24} {} samples  {}  {}", s.name, s.size, s.wavelengths.describe(), s.units);
}

std::string grid_line(const store::GridInfo& g) {
  return fmt::format("grid        {:<24} {}  {}  parameterisation: {}", g.name, g.wavelengths.describe(), g.units,
                     store::parameterisation_text(g));
}

std::string coefficients_line(const store::CoefficientsInfo& c) {
  return fmt::format("coefficients {:<23} {}x{}  {} {} coefficients of image {} on basis {}  [{}]", c.name, c.height,
                     c.width, c.k, c.method, c.image, c.basis, c.compression);
}

// Every object of the store as lines for people.
void list_objects(const store::Store& s) {
  for (const auto& n : s.images()) fmt::print("{}\n", image_line(s.image_info(n)));
  for (const auto& n : s.collections()) fmt::print("{}\n", collection_line(s.collection_info(n)));
  for (const auto& n : s.samples()) fmt::print("{}\n", samples_line(s.samples_info(n)));
  for (const auto& n : s.grids()) fmt::print("{}\n", grid_line(s.grid_info(n)));
  for (const auto& n : s.bases()) fmt::print("basis       {}\n", n);
  for (const auto& n : s.coefficients()) fmt::print("{}\n", coefficients_line(s.coefficients_info(n)));
  for (const auto& n : s.objects("acquire")) {
    const acquire::Calibration c = acquire::read_calibration(s, n);
    fmt::print("calibration {:<24} {} spectral model, {} lights, sphere {:.4f} m at {:.4f} m\n", n,
               acquire::spectral_model_name(c.spectral.model), c.light_dirs.size(), c.sphere.radius,
               c.sphere.centre.norm());
  }
}

void run_info(const InfoOptions& o) {
  const store::Store s = store::Store::open(o.store);
  if (o.object.empty()) {
    if (o.json) return print_json(acquire::store_info_json(s));
    const std::uint64_t spectra = store::valid_spectra(s);
    const auto bytes = store::store_bytes(s);
    const std::string created = s.created_utc();
    fmt::print("{}: specula store, format version {}{}, {:.1f} MB, created {}\n", s.path().string(), s.format_version(),
               s.format_version() < store::kFormatVersion
                   ? fmt::format(" (read-only here: `specula upgrade {}` converts it in place)", s.path().string())
                   : fmt::format(", generation {}", s.index().generation),
               double(bytes) / 1e6, created);
    fmt::print("{} images ({} valid spectra), {} collections, {} sample sets, {} grids, {} bases\n", s.images().size(),
               spectra, s.collections().size(), s.samples().size(), s.grids().size(), s.bases().size());
    list_objects(s);
    return;
  }
  std::string name = o.object;
  for (const char* prefix : {"images/", "collections/", "samples/", "grids/", "bases/", "coefficients/", "/images/",
                             "/collections/", "/samples/", "/grids/", "/bases/", "/coefficients/"})
    if (name.rfind(prefix, 0) == 0) name = name.substr(std::string(prefix).size());
  auto has = [](const std::vector<std::string>& v, const std::string& n) {
    return std::find(v.begin(), v.end(), n) != v.end();
  };
  if (has(s.images(), name)) {
    const auto i = s.image_info(name);
    if (o.json) return print_json(store::image_json(i));
    fmt::print("{}\n  wavelengths {}\n  source {} (importer {})\n  created {} by: {}\n", image_line(i),
               fmt::format("[{}]", fmt::join(i.wavelengths.values(), ",")), i.provenance.source_file,
               i.provenance.importer, i.provenance.created_utc, i.provenance.command_line);
  } else if (has(s.collections(), name)) {
    const auto c = s.collection_info(name);
    if (o.json) return print_json(store::collection_json(c));
    fmt::print("{}\n  source {}\n  created {} by: {}\n", collection_line(c), c.provenance.source_file,
               c.provenance.created_utc, c.provenance.command_line);
  } else if (has(s.samples(), name)) {
    const auto c = s.samples_info(name);
    if (o.json) return print_json(store::samples_json(c));
    fmt::print("{}\n  source {}\n", samples_line(c), c.provenance.source_file);
  } else if (has(s.grids(), name)) {
    const auto g = s.grid_info(name);
    if (o.json) return print_json(store::grid_json(g));
    fmt::print("{}\n  source {}\n  created {} by: {}\n", grid_line(g), g.provenance.source_file,
               g.provenance.created_utc, g.provenance.command_line);
  } else if (has(s.bases(), name)) {
    const store::Basis b = s.read_basis(name);
    if (o.json) return print_json(store::basis_json(name, b));
    fmt::print(
        "basis {}: {}, {} components on {}, learned from {} spectra\n  source {}\n  fit {}\n  created {} by: {}\n",
        name, b.method, b.k(), b.wavelengths.describe(), b.n, b.source, b.provenance.importer, b.provenance.created_utc,
        b.provenance.command_line);
  } else if (has(s.coefficients(), name)) {
    const auto c = s.coefficients_info(name);
    if (o.json) return print_json(store::coefficients_json(c));
    fmt::print("{}\n  created {} by: {}\n", coefficients_line(c), c.provenance.created_utc, c.provenance.command_line);
  } else {
    throw InputError(s.label() + ": no object '" + o.object + "'; `specula ls " + s.path().string() + "` lists them");
  }
}

}  // namespace

void setup_info(CLI::App& app) {
  auto o = std::make_shared<InfoOptions>();
  auto* cmd = app.add_subcommand("info", "Describe a store, or one object in it");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("object", o->object, "Object name (image, collection, samples, grid, basis or coefficient map)");
  cmd->add_flag("--json", o->json, "Print JSON");
  cmd->callback([o] { run_info(*o); });
}

void setup_ls(CLI::App& app) {
  auto store = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("ls", "List the objects in a store, one per line");
  cmd->add_option("store", *store, "Store file")->required();
  cmd->callback([store] { list_objects(store::Store::open(*store)); });
}

}  // namespace specula::app
