// specula info and specula ls: what a store holds, for people (text) and programs (--json).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/pipeline.h"
#include "specula/core/error.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct InfoOptions {
  std::string store;
  std::string object;
  bool json = false;
};

Json provenance_json(const store::Provenance& p) {
  return {{"source_file", p.source_file},
          {"importer", p.importer},
          {"command_line", p.command_line},
          {"created_utc", p.created_utc}};
}

Json image_json(const store::ImageInfo& i) {
  return {{"kind", "image"},         {"name", i.name},
          {"height", i.height},      {"width", i.width},
          {"bands", i.bands},        {"wavelengths", json_numbers(i.wavelengths.values())},
          {"units", i.units},        {"valid_pixels", i.valid_pixels},
          {"chunk_rows", i.chunk_rows}, {"compression", i.compression},
          {"has_fwhm", i.has_fwhm},  {"provenance", provenance_json(i.provenance)}};
}

Json collection_json(const store::CollectionInfo& c) {
  return {{"kind", "collection"}, {"name", c.name},   {"size", c.size},
          {"bands", c.bands},     {"wavelengths", json_numbers(c.wavelengths.values())},
          {"units", c.units},     {"provenance", provenance_json(c.provenance)}};
}

Json samples_json(const store::SamplesInfo& s) {
  return {{"kind", "samples"}, {"name", s.name},   {"size", s.size},
          {"bands", s.bands},  {"wavelengths", json_numbers(s.wavelengths.values())},
          {"units", s.units},  {"provenance", provenance_json(s.provenance)}};
}

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

Json coefficients_json(const store::CoefficientsInfo& c) {
  return {{"kind", "coefficients"}, {"name", c.name},     {"image", c.image},
          {"basis", c.basis},       {"method", c.method}, {"height", c.height},
          {"width", c.width},       {"k", c.k},           {"valid_pixels", c.valid_pixels},
          {"provenance", provenance_json(c.provenance)}};
}

Json basis_json(const std::string& name, const store::Basis& b) {
  return {{"kind", "basis"},
          {"name", name},
          {"method", b.method},
          {"k", b.k()},
          {"n", b.n},
          {"bands", b.bands()},
          {"wavelengths", json_numbers(b.wavelengths.values())},
          {"source", b.source},
          {"fit", b.provenance.importer},
          {"created", b.provenance.created_utc},
          {"command_line", b.provenance.command_line}};
}

std::string coefficients_line(const store::CoefficientsInfo& c) {
  return fmt::format("coefficients {:<23} {}x{}  {} {} coefficients of image {} on basis {}  [{}]", c.name, c.height,
                     c.width, c.k, c.method, c.image, c.basis, c.compression);
}

// Every object of the store, as JSON objects, or as lines for people.
Json object_list(const store::Store& s) {
  Json rows = Json::array();
  for (const auto& n : s.images()) rows.push_back(image_json(s.image_info(n)));
  for (const auto& n : s.collections()) rows.push_back(collection_json(s.collection_info(n)));
  for (const auto& n : s.samples()) rows.push_back(samples_json(s.samples_info(n)));
  for (const auto& n : s.grids()) rows.push_back({{"kind", "grid"}, {"name", n}});
  for (const auto& n : s.bases()) rows.push_back({{"kind", "basis"}, {"name", n}});
  for (const auto& n : s.coefficients()) rows.push_back(coefficients_json(s.coefficients_info(n)));
  for (const auto& n : s.objects("acquire")) {
    const acquire::Calibration c = acquire::read_calibration(s, n);
    rows.push_back({{"kind", "calibration"},
                    {"name", n},
                    {"spectral_model", c.spectral.model == acquire::SpectralModel::delta ? "delta" : "factored"},
                    {"lights", c.light_dirs.size()}});
  }
  return rows;
}

void list_objects(const store::Store& s) {
  for (const auto& n : s.images()) fmt::print("{}\n", image_line(s.image_info(n)));
  for (const auto& n : s.collections()) fmt::print("{}\n", collection_line(s.collection_info(n)));
  for (const auto& n : s.samples()) fmt::print("{}\n", samples_line(s.samples_info(n)));
  for (const auto& n : s.grids()) fmt::print("grid        {}\n", n);
  for (const auto& n : s.bases()) fmt::print("basis       {}\n", n);
  for (const auto& n : s.coefficients()) fmt::print("{}\n", coefficients_line(s.coefficients_info(n)));
  for (const auto& n : s.objects("acquire")) {
    const acquire::Calibration c = acquire::read_calibration(s, n);
    fmt::print("calibration {:<24} {} spectral model, {} lights, sphere {:.4f} m at {:.4f} m\n", n,
               c.spectral.model == acquire::SpectralModel::delta ? "delta" : "factored", c.light_dirs.size(),
               c.sphere.radius, c.sphere.centre.norm());
  }
}

void run_info(const InfoOptions& o) {
  const store::Store s = store::Store::open(o.store);
  if (o.object.empty()) {
    std::uint64_t spectra = 0;
    for (const auto& n : s.images()) spectra += s.image_info(n).valid_pixels;
    const auto bytes = store::store_bytes(s);
    const std::string created = s.created_utc();
    if (o.json) {
      print_json({{"store", s.path().string()},
                  {"format_version", s.format_version()},
                  {"generation", s.index().generation},
                  {"bytes", bytes},
                  {"created_utc", created},
                  {"valid_spectra", spectra},
                  {"objects", object_list(s)}});
      return;
    }
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
  for (const char* prefix : {"images/", "collections/", "samples/", "bases/", "coefficients/", "/images/",
                             "/collections/", "/samples/", "/bases/", "/coefficients/"})
    if (name.rfind(prefix, 0) == 0) name = name.substr(std::string(prefix).size());
  auto has = [](const std::vector<std::string>& v, const std::string& n) {
    return std::find(v.begin(), v.end(), n) != v.end();
  };
  if (has(s.images(), name)) {
    const auto i = s.image_info(name);
    if (o.json) return print_json(image_json(i));
    fmt::print("{}\n  wavelengths {}\n  source {} (importer {})\n  created {} by: {}\n", image_line(i),
               fmt::format("[{}]", fmt::join(i.wavelengths.values(), ",")), i.provenance.source_file, i.provenance.importer,
               i.provenance.created_utc, i.provenance.command_line);
  } else if (has(s.collections(), name)) {
    const auto c = s.collection_info(name);
    if (o.json) return print_json(collection_json(c));
    fmt::print("{}\n  source {}\n  created {} by: {}\n", collection_line(c), c.provenance.source_file,
               c.provenance.created_utc, c.provenance.command_line);
  } else if (has(s.samples(), name)) {
    const auto c = s.samples_info(name);
    if (o.json) return print_json(samples_json(c));
    fmt::print("{}\n  source {}\n", samples_line(c), c.provenance.source_file);
  } else if (has(s.bases(), name)) {
    const store::Basis b = s.read_basis(name);
    if (o.json) return print_json(basis_json(name, b));
    fmt::print(
        "basis {}: {}, {} components on {}, learned from {} spectra\n  source {}\n  fit {}\n  created {} by: {}\n",
        name, b.method, b.k(), b.wavelengths.describe(), b.n, b.source, b.provenance.importer, b.provenance.created_utc,
        b.provenance.command_line);
  } else if (has(s.coefficients(), name)) {
    const auto c = s.coefficients_info(name);
    if (o.json) return print_json(coefficients_json(c));
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
  cmd->add_option("object", o->object, "Object name (image, collection, samples, basis or coefficient map)");
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
