// RGL .bsdf materials (codec/rgl_bsdf.h): read as the renderers evaluate them at the MERL cell centres, written
// from a Grid.
#include <optional>
#include <string>

#include "python/common.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_export.h"
#include "specula/codec/rgl_target.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula::python {
namespace {

py::object write_bsdf(const py::object& p, const store::Grid& g, bool rgb, std::size_t theta_i, std::size_t resolution,
                      const std::string& description, std::optional<double> target_de00,
                      std::optional<double> target_p95, const std::string& parameterisation) {
  if (target_p95 && !target_de00) throw UsageError("write_bsdf: target_p95 goes with target_de00");
  if (target_de00 && rgb) throw UsageError("write_bsdf: target_de00 judges the spectral file; drop rgb");
  const std::string path = path_from(p).string();
  const codec::RglExportSettings s{.theta_i = theta_i,
                                   .resolution = resolution,
                                   .description = description,
                                   .parameterisation = codec::parse_rgl_parameterisation(parameterisation)};
  codec::RglTargetReport report;
  {
    py::gil_scoped_release release;
    codec::RglBsdf b;
    if (target_de00) {
      const codec::RglTarget t{.de00_mean = *target_de00,
                               .de00_p95 = target_p95.value_or(codec::default_p95_target(*target_de00))};
      b = codec::export_rgl_to_target(g, s, t, codec::LightingSuite(g.wavelengths), report);
    } else {
      const auto weights = codec::rgb_weights(g.wavelengths, illuminant("D65", g.wavelengths));
      codec::RglParameterisation used;
      b = codec::export_rgl_judged(g, s, codec::LightingSuite(g.wavelengths), used, rgb ? &weights : nullptr);
    }
    codec::write_rgl_bsdf(path, b);
  }
  if (!target_de00) return py::none();
  py::list trials;
  for (const auto& t : report.trials)
    trials.append(py::dict(py::arg("theta_i") = t.theta_i, py::arg("resolution") = t.resolution,
                           py::arg("bytes") = t.bytes, py::arg("de00_mean") = t.de00_mean,
                           py::arg("de00_p95") = t.de00_p95, py::arg("met") = t.met,
                           py::arg("parameterisation") = codec::rgl_parameterisation_name(t.parameterisation)));
  return py::dict(py::arg("reached") = report.reached, py::arg("trials") = trials);
}

}  // namespace

void init_bsdf(py::module_& m) {
  m.def(
      "read_bsdf",
      [](const PathArg& p) -> py::object {
        const std::string path = existing_file(p).string();
        codec::RglBsdf b = codec::read_rgl_bsdf(path);
        if (!b.rgb) {
          store::Grid g;
          {
            py::gil_scoped_release release;
            g = codec::rgl_to_grid(b, path);
          }
          return py::cast(std::move(g));
        }
        std::vector<float> v;
        {
          py::gil_scoped_release release;
          v = codec::rgl_merl_values(b);
        }
        return adopt(std::move(v), {3, brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD});
      },
      py::arg("path"),
      "An RGL .bsdf evaluated at every MERL cell centre as Mitsuba 3 and pbrt-v4 evaluate it: a spectral file as a "
      "Grid on its wavelengths, an RGB file as (3, 90, 90, 180) float32 BRDF values in 1/sr (-1: below the horizon).");
  m.def("write_bsdf", &write_bsdf, py::arg("path"), py::arg("grid"), py::arg("rgb") = false, py::arg("theta_i") = 8,
        py::arg("resolution") = 32, py::arg("description") = "", py::arg("target_de00") = py::none(),
        py::arg("target_p95") = py::none(), py::arg("parameterisation") = "auto",
        "Writes grid as an isotropic RGL .bsdf (spectral, or RGB under D65 with rgb=True) that Mitsuba 3 and pbrt-v4 "
        "read; complete or not at all (docs/brdf.md). With target_de00 (spectral only) the smallest (theta_i, "
        "resolution) of the ladder, from the one given, whose import the lighting suite finds within ΔE00 mean "
        "target_de00 and 95th percentile target_p95 (default 3x), as `specula export --target-de00`; returns then "
        "{'reached': bool, 'trials': [{'theta_i', 'resolution', 'bytes', 'de00_mean', 'de00_p95', 'met', "
        "'parameterisation'}, ...]} (the largest tried is written when none meets it), else None. parameterisation: "
        "auto (a grid read from a .bsdf, or from a store it was imported into, is tabulated on its source file's "
        "tables when theta_i and resolution are the source's), source or estimate, as `export --parameterisation`.");
}

}  // namespace specula::python
