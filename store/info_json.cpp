#include "specula/store/info_json.h"

#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

namespace specula::store {
namespace {

using Json = nlohmann::ordered_json;

Json numbers(std::span<const double> v) { return Json(std::vector<double>(v.begin(), v.end())); }

Json provenance_json(const Provenance& p) {
  return {{"source_file", p.source_file},
          {"importer", p.importer},
          {"command_line", p.command_line},
          {"created_utc", p.created_utc}};
}

}  // namespace

Json image_json(const ImageInfo& i) {
  return {{"kind", "image"},
          {"name", i.name},
          {"height", i.height},
          {"width", i.width},
          {"bands", i.bands},
          {"wavelengths", numbers(i.wavelengths.values())},
          {"units", i.units},
          {"valid_pixels", i.valid_pixels},
          {"chunk_rows", i.chunk_rows},
          {"compression", i.compression},
          {"has_fwhm", i.has_fwhm},
          {"provenance", provenance_json(i.provenance)}};
}

Json collection_json(const CollectionInfo& c) {
  return {{"kind", "collection"},
          {"name", c.name},
          {"size", c.size},
          {"bands", c.bands},
          {"wavelengths", numbers(c.wavelengths.values())},
          {"units", c.units},
          {"provenance", provenance_json(c.provenance)}};
}

Json samples_json(const SamplesInfo& s) {
  return {{"kind", "samples"},
          {"name", s.name},
          {"size", s.size},
          {"bands", s.bands},
          {"wavelengths", numbers(s.wavelengths.values())},
          {"units", s.units},
          {"variance", s.variance},
          {"provenance", provenance_json(s.provenance)}};
}

Json coefficients_json(const CoefficientsInfo& c) {
  return {{"kind", "coefficients"},
          {"name", c.name},
          {"image", c.image},
          {"basis", c.basis},
          {"method", c.method},
          {"height", c.height},
          {"width", c.width},
          {"k", c.k},
          {"valid_pixels", c.valid_pixels},
          {"provenance", provenance_json(c.provenance)}};
}

Json grid_json(const GridInfo& g) {
  Json p = nullptr;
  if (const auto& s = g.parameterisation) {
    const auto table = [](std::size_t height, std::size_t width) { return Json{{"height", height}, {"width", width}}; };
    p = {{"source", "rgl"},
         {"description", s->description},
         {"theta_i", Json(s->theta_i)},
         {"ndf", table(s->ndf_height, s->ndf_width)},
         {"sigma", table(s->sigma_height, s->sigma_width)},
         {"vndf", table(s->vndf_height, s->vndf_width)},
         {"resolution", s->resolution}};
  }
  return {{"kind", "grid"},
          {"name", g.name},
          {"bands", g.bands},
          {"wavelengths", numbers(g.wavelengths.values())},
          {"scale", g.scale},
          {"units", g.units},
          {"compression", g.compression},
          {"parameterisation", p},
          {"provenance", provenance_json(g.provenance)}};
}

std::string parameterisation_text(const GridInfo& g) {
  if (!g.parameterisation) return "none";
  const GridParameterisation& p = *g.parameterisation;
  const auto size = [](std::size_t height, std::size_t width) {
    return height == width ? std::to_string(width) + "^2" : std::to_string(width) + "x" + std::to_string(height);
  };
  return "source tables (RGL), " + std::to_string(p.theta_i.size()) + " theta_i, ndf " +
         size(p.ndf_height, p.ndf_width) + ", vndf " + size(p.vndf_height, p.vndf_width) + ", " +
         size(p.resolution, p.resolution) + " sample grid";
}

Json basis_json(const std::string& name, const Basis& b) {
  return {{"kind", "basis"},
          {"name", name},
          {"method", b.method},
          {"k", b.k()},
          {"n", b.n},
          {"bands", b.bands()},
          {"wavelengths", numbers(b.wavelengths.values())},
          {"source", b.source},
          {"fit", b.provenance.importer},
          {"created", b.provenance.created_utc},
          {"command_line", b.provenance.command_line}};
}

Json objects_json(const Store& s) {
  Json rows = Json::array();
  for (const auto& n : s.images()) rows.push_back(image_json(s.image_info(n)));
  for (const auto& n : s.collections()) rows.push_back(collection_json(s.collection_info(n)));
  for (const auto& n : s.samples()) rows.push_back(samples_json(s.samples_info(n)));
  for (const auto& n : s.grids()) rows.push_back(grid_json(s.grid_info(n)));
  for (const auto& n : s.bases()) rows.push_back({{"kind", "basis"}, {"name", n}});
  for (const auto& n : s.coefficients()) rows.push_back(coefficients_json(s.coefficients_info(n)));
  return rows;
}

std::uint64_t valid_spectra(const Store& s) {
  std::uint64_t spectra = 0;
  for (const auto& n : s.images()) spectra += s.image_info(n).valid_pixels;
  return spectra;
}

Json store_json(const Store& s) {
  const std::uint64_t spectra = valid_spectra(s);
  return {{"store", s.path().string()}, {"format_version", s.format_version()}, {"generation", s.index().generation},
          {"bytes", store_bytes(s)},    {"created_utc", s.created_utc()},       {"valid_spectra", spectra},
          {"objects", objects_json(s)}};
}

}  // namespace specula::store
