// RGL .bsdf materials (codec/rgl_bsdf.h): read as the renderers evaluate them at the MERL cell centres, written
// from a Grid.
#include <string>

#include "python/common.h"
#include "specula/codec/rgl_eval.h"
#include "specula/codec/rgl_export.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula::python {
namespace {}  // namespace

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
  m.def(
      "write_bsdf",
      [](const py::object& p, const store::Grid& g, bool rgb, std::size_t theta_i, std::size_t resolution,
         const std::string& description) {
        const std::string path = path_from(p).string();
        py::gil_scoped_release release;
        const codec::RglExportSettings s{.theta_i = theta_i, .resolution = resolution, .description = description};
        const codec::RglBsdf b =
            rgb ? codec::export_rgl(
                      codec::grid_to_merl(g, codec::rgb_weights(g.wavelengths, illuminant("D65", g.wavelengths))).brdf,
                      s)
                : codec::export_rgl(g, s);
        codec::write_rgl_bsdf(path, b);
      },
      py::arg("path"), py::arg("grid"), py::arg("rgb") = false, py::arg("theta_i") = 8, py::arg("resolution") = 32,
      py::arg("description") = "",
      "Writes grid as an isotropic RGL .bsdf (spectral, or RGB under D65 with rgb=True) that Mitsuba 3 and pbrt-v4 "
      "read; complete or not at all (docs/brdf.md).");
}

}  // namespace specula::python
