#include "specula/acquire/prior_output.h"

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::acquire {

std::string confidence_name(const std::string& name) { return name + ".confidence"; }

std::filesystem::path confidence_path(const std::filesystem::path& path) {
  return path.parent_path() / (path.stem().string() + ".confidence" + path.extension().string());
}

store::Grid confidence_grid(std::span<const float> confidence, const WavelengthGrid& bands) {
  if (confidence.size() != brdf::kMerlCells || bands.size() == 0)
    throw UsageError("prior: a confidence grid takes one value per MERL cell and the samples' bands");
  store::Grid g;
  g.wavelengths = WavelengthGrid({bands[bands.size() / 2]});
  g.units = "confidence";
  g.brdf.assign(confidence.begin(), confidence.end());
  return g;
}

void add_prior_grids(store::StoreWriter& out, const std::string& name, const store::Grid& grid,
                     const store::Grid& confidence) {
  store::validate_name(name, "grid");
  store::validate_name(confidence_name(name), "grid");
  out.add_grid(name, grid);
  out.add_grid(confidence_name(name), confidence);
}

}  // namespace specula::acquire
