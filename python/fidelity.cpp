// specula.compare_grids: how far a BRDF grid is from a reference, in value and rendered (codec::diff_grids, the
// comparison `specula brdf-diff` prints). The one place the Python module binds the fidelity comparison.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "python/common.h"
#include "specula/codec/diff.h"
#include "specula/codec/environment.h"
#include "specula/codec/report_json.h"
#include "specula/codec/suite.h"

namespace specula::python {

void init_fidelity(py::module_& m) {
  m.def(
      "compare_grids",
      [](const GridArg& a_arg, const GridArg& b_arg, const EnvArg& env_arg, std::size_t size) {
        const store::Grid& a = as<store::Grid>(a_arg, "compare_grids", "reference", "Grid");
        const store::Grid& b = as<store::Grid>(b_arg, "compare_grids", "grid", "Grid");
        if (size < 8 || size > 4096)
          throw UsageError(fmt::format("compare_grids: size {}: give 8 to 4096 pixels", size));
        const codec::Environment env = environment_from(env_arg, a.wavelengths);
        codec::GridDiff d;
        {
          py::gil_scoped_release release;
          d = codec::diff_grids(a, b, env, {.size = size});
        }
        // the fields of `specula brdf-diff --json`, and the per-pixel CIEDE2000 map
        py::dict r = py::module_::import("json").attr("loads")(codec::grid_diff_json(d, env.description, size).dump());
        r["de00"] = adopt(std::move(d.de00), {py::ssize_t(size), py::ssize_t(size)});
        return r;
      },
      py::arg("reference"), py::arg("grid"), py::arg("env") = "default", py::arg("size") = 128,
      "Compares `grid` with `reference` (specula.Grid on one wavelength grid) as `specula brdf-diff --json` does: "
      "cells (valid in both), only_a, only_b, rms and max_abs (1/sr), rel_rms_cos (cosine-weighted relative RMS), and "
      "both rendered on a `size`-pixel sphere under `env` ('default' or a lat-long EXR): de00_mean, de00_p95, "
      "de00_max and the per-pixel CIEDE2000 map de00 (size, size) float32 (0 off the sphere).");
  m.def(
      "fidelity",
      [](const GridArg& a_arg, const GridArg& b_arg, const EnvArg& env_arg, std::size_t size) {
        const store::Grid& a = as<store::Grid>(a_arg, "fidelity", "reference", "Grid");
        const store::Grid& b = as<store::Grid>(b_arg, "fidelity", "grid", "Grid");
        if (size < 16 || size > 1024) throw UsageError(fmt::format("fidelity: size {}: give 16 to 1024 pixels", size));
        const codec::Environment env = environment_from(env_arg, a.wavelengths);
        std::string json;
        {
          py::gil_scoped_release release;
          const codec::LightingSuite suite(env, {.size = size});
          json = codec::suite_json(codec::suite_diff(a, b, suite), suite);
        }
        return py::module_::import("json").attr("loads")(json).cast<py::dict>();
      },
      py::arg("reference"), py::arg("grid"), py::arg("env") = "default", py::arg("size") = 64,
      "The lighting suite (docs/brdf.md) of `grid` against `reference` as `specula brdf-diff --json` reports it: "
      "pooled de00_mean, de00_p95, de00_max, the worst condition, holes, rel_rms_cos, albedo errors and every "
      "condition; `env` replaces the built-in environment ('default' or a lat-long EXR).");
}

}  // namespace specula::python
