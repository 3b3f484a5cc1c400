// specula import: files into a store through store::import_files (store/import.h, docs/import.md), all in one
// transaction (all or nothing).
#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <utility>
#include <vector>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/nbrdf.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/store/import.h"
#include "specula/store/io/nbrdf.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct ImportOptions {
  std::vector<std::string> inputs;
  std::string output;
  std::string name;
  std::string wavelengths;
  std::string source_wavelengths;
  std::string mask;
  std::string var;  // empty: detected from the file (store/io/mat.h)
  std::string format = "auto";
  std::string nan = "reject";
  std::string compression = "deflate";
  std::string units;
  bool replace = false;
  bool keep_bad_bands = false;
  bool strict = false;
  bool uplift = false;
  std::string illuminant = "D65";
  unsigned jobs = 1;
  double memory_gib = 1.0;
};

std::string with_flags(std::string m);

// RGL .bsdf materials become grids evaluated at the MERL cell centres (RGB ones uplifted), in one transaction.
void import_bsdf(const ImportOptions& o) {
  if (!o.name.empty() && o.inputs.size() > 1)
    throw UsageError("import: --name names one .bsdf file; " + std::to_string(o.inputs.size()) + " given");
  // RGB files are uplifted onto --wavelengths (default 400-700 nm step 10); spectral ones keep their own.
  const WavelengthGrid onto =
      o.wavelengths.empty() ? default_uplift_wavelengths() : WavelengthGrid::parse(o.wavelengths);
  std::vector<std::pair<std::string, store::Grid>> grids;
  for (const auto& in : o.inputs) {
    grids.emplace_back(o.name.empty() ? std::filesystem::path(in).stem().string() : o.name,
                       load_grid(in, "import", onto));
    grids.back().second.provenance.command_line = command_line();
  }
  store::StoreWriter writer(
      o.output,
      {.compression = store::Compression::parse(o.compression), .replace = o.replace, .command_line = command_line()});
  for (const auto& [name, grid] : grids) writer.add_grid(name, grid);
  writer.commit();
  for (const auto& [name, grid] : grids)
    fmt::print("imported grid '{}' ({}{}) into {}\n", name, grid.wavelengths.describe(),
               grid.provenance.importer == "uplift-clamp" ? ", uplifted from RGB" : "", o.output);
}

// Neural BRDF weights (.h5, docs/import.md): evaluated on the MERL grid and uplifted to spectral grids.
bool is_nbrdf_import(const ImportOptions& o) {
  if (o.format == "nbrdf") return true;
  if (o.format != "auto") return false;
  for (const auto& in : o.inputs) {
    std::error_code ec;
    if (std::filesystem::is_directory(in, ec)) {  // a directory of NBRDFs: all its .h5 files are
      bool any = false;
      for (const auto& e : std::filesystem::directory_iterator(in, ec)) {
        if (e.path().extension() != ".h5") continue;
        if (!store::is_nbrdf(e.path())) return false;
        any = true;
      }
      if (!any) return false;
    } else if (std::filesystem::path(in).extension() != ".h5" || !store::is_nbrdf(in)) {
      return false;
    }
  }
  return true;
}

void run_nbrdf_import(const ImportOptions& o) {
  const std::vector<std::filesystem::path> inputs(o.inputs.begin(), o.inputs.end());
  const auto files = codec::nbrdf_files(inputs);
  if (std::filesystem::path(o.output).extension() == ".binary") {
    if (files.size() != 1) throw UsageError("import: -o X.binary takes one NBRDF file");
    codec::NbrdfGridReport report;
    codec::write_merl(o.output, codec::nbrdf_to_merl(store::read_nbrdf(files[0]), &report));
    fmt::print("{} -> {}: NBRDF at {} cell centres ({} negative channel values set to 0)\n", files[0].string(),
               o.output, report.cells, report.clamped);
    return;
  }
  if (!o.uplift)
    throw UsageError(
        "import: a store holds spectral grids: pass --uplift to turn the NBRDF's RGB into spectra "
        "(Appendix A, onto --wavelengths), or evaluate it to an RGB MERL .binary with `specula "
        "import X.h5 --format nbrdf -o X.binary`");
  codec::NbrdfImportOptions options;
  options.name = o.name;
  options.wavelengths = WavelengthGrid::parse(o.wavelengths.empty() ? "400:700:10" : o.wavelengths);
  options.illuminant = parse_illuminant(o.illuminant, options.wavelengths);
  store::StoreWriter writer(
      o.output,
      {.compression = store::Compression::parse(o.compression), .replace = o.replace, .command_line = command_line()});
  const auto lines = codec::import_nbrdf(writer, files, options);
  writer.commit();
  for (const auto& line : lines) fmt::print("{}\n", line);
}

void run_import(const ImportOptions& o) {
  if (is_nbrdf_import(o)) return run_nbrdf_import(o);
  if (!o.inputs.empty() && std::all_of(o.inputs.begin(), o.inputs.end(), [](const std::string& i) {
        return std::filesystem::path(i).extension() == ".bsdf";
      }))
    return import_bsdf(o);
  store::ImportOptions options;
  options.name = o.name;
  if (!o.wavelengths.empty()) options.wavelengths = WavelengthGrid::parse(o.wavelengths);
  if (!o.source_wavelengths.empty()) options.source_wavelengths = WavelengthGrid::parse(o.source_wavelengths);
  options.mask = o.mask;
  options.var = o.var;
  options.format = o.format;
  options.nan = o.nan == "mask" ? store::NanPolicy::mask : store::NanPolicy::reject;
  options.units = o.units;
  options.honour_bbl = !o.keep_bad_bands;
  options.strict = o.strict;
  options.jobs = o.jobs;
  options.memory_budget = std::uint64_t(o.memory_gib * double(std::uint64_t{1} << 30));
  const std::vector<std::filesystem::path> inputs(o.inputs.begin(), o.inputs.end());

  store::StoreWriter writer(
      o.output,
      {.compression = store::Compression::parse(o.compression), .replace = o.replace, .command_line = command_line()});
  const store::ImportReport report = store::import_files(writer, inputs, options);
  writer.commit();
  for (const auto& skip : report.skipped) fmt::print(stderr, "{}\n", with_flags(skip));
  for (const auto& note : report.notes) fmt::print(stderr, "{}\n", note);
  for (const auto& line : report.imported) fmt::print("{}\n", line);  // only once everything has landed
}

// The library names its options; on the command line they are flags.
std::string with_flags(std::string m) {
  for (const auto& [param, flag] : {std::pair<std::string, std::string>{"the `wavelengths` option", "--wavelengths"},
                                    {"the `var` option", "--var"},
                                    {"the `nan` option", "--nan"},
                                    {"the `name` option", "--name"},
                                    {"the `format` option", "--format"},
                                    {"the `mask` option", "--mask"},
                                    {"import without `strict`", "import without --strict"},
                                    {"the `strict` option", "--strict"},
                                    {"pass honour_bbl = false", "pass --keep-bad-bands"}})
    for (std::size_t at; (at = m.find(param)) != std::string::npos;) m.replace(at, param.size(), flag);
  return m;
}

}  // namespace

void setup_import(CLI::App& app) {
  auto o = std::make_shared<ImportOptions>();
  auto* cmd =
      app.add_subcommand("import",
                         "Import spectral images (ENVI, .mat, PNG stack, spectral EXR, GeoTIFF and other GDAL rasters) "
                         "and spectral libraries (CSV, .mat, ENVI .sli, USGS, ECOSTRESS) and RGL .bsdf materials (as "
                         "BRDF grids) into a store, whole directories in one transaction (docs/import.md)");
  cmd->add_option("inputs", o->inputs,
                  "Files, directories or quoted glob patterns ('db/*.mat'). A directory or pattern imports every file "
                  "it holds that a reader recognises and prints a line for each file it skips; a directory whose only "
                  "recognised files are PNGs is one band stack, as are PNG files named together")
      ->required();
  cmd->add_option("-o,--output", o->output, "Store to create or add to")->required();
  cmd->add_option("--name", o->name, "Object name (default: the file name without extension)");
  cmd->add_option("--wavelengths", o->wavelengths,
                  "Target grid FIRST:LAST:STEP or a comma list; data is resampled linearly onto it (no extrapolation). "
                  "Also the data's own grid when it carries none (PNG stacks)");
  cmd->add_option("--source-wavelengths", o->source_wavelengths,
                  "The data's own grid when it carries none and --wavelengths resamples");
  cmd->add_option("--mask", o->mask,
                  "Mask: a PNG or a one-band ENVI image (nonzero = valid), or for .mat the name of a mask variable");
  cmd->add_option("--var", o->var,
                  "Cube or spectra variable in a .mat file (default: detected, e.g. ref, rad, cube, Y, data)");
  cmd->add_option("--format", o->format,
                  "auto, envi, mat, png, exr, csv, usgs (splib07a ASCII), ecostress, gdal (any raster GDAL reads; "
                  ".tif/.tiff are gdal by default) or nbrdf (Keras weights of a neural BRDF; .h5 files holding dense_1 "
                  "are nbrdf by default)")
      ->check(CLI::IsMember({"auto", "envi", "mat", "png", "exr", "csv", "usgs", "ecostress", "gdal", "nbrdf"}))
      ->capture_default_str();
  cmd->add_option("--nan", o->nan, "NaN/Inf in valid pixels: reject (default) or mask")
      ->check(CLI::IsMember({"reject", "mask"}))
      ->capture_default_str();
  cmd->add_option("--compression", o->compression, "none, deflate or deflate:LEVEL (shuffle + deflate)")
      ->capture_default_str();
  cmd->add_option("--units", o->units, "Override the units: reflectance, radiance, counts, ...");
  cmd->add_flag("--replace", o->replace, "Replace objects of the same name");
  cmd->add_flag("--strict", o->strict, "Any file skipped in a directory or pattern is an error (nothing is imported)");
  cmd->add_option("--jobs", o->jobs,
                  "Files read at once, at most, within --memory (1 keeps every core for each file's compression); the "
                  "store's content does not depend on it")
      ->check(CLI::Range(1u, 256u))
      ->capture_default_str();
  cmd->add_option("--memory", o->memory_gib,
                  "GiB the files read at once may take, estimated from their headers (a larger file is read alone; "
                  "GDAL rasters are streamed by row strips)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_flag("--uplift", o->uplift,
                "NBRDF: turn the network's RGB into spectra on --wavelengths (default 400:700:10) by Appendix A, "
                "non-negative");
  cmd->add_option("--illuminant", o->illuminant,
                  "NBRDF --uplift: illuminant under which the RGB was seen (as for uplift)")
      ->capture_default_str();
  cmd->add_flag("--keep-bad-bands", o->keep_bad_bands,
                "Keep the bands an ENVI header's bbl marks bad (dropped by default)");
  cmd->callback([o] {
    try {
      run_import(*o);
    } catch (const InputError& e) {
      throw InputError(with_flags(e.what()));
    } catch (const UsageError& e) {
      throw UsageError(with_flags(e.what()));
    }
  });
}

}  // namespace specula::app
