// The BRDF half's pictures and evaluation: render_sphere (what `specula render` draws, as arrays) and SpcBrdf (a
// .spc evaluated at direction pairs from its coefficients, never decoded to a grid).
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "python/common.h"
#include "specula/codec/environment.h"
#include "specula/codec/merl.h"
#include "specula/codec/render.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_eval.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/buffer.h"
#include "specula/core/colour.h"
#include "specula/core/illuminant.h"
#include "specula/core/preview.h"

namespace specula::python {
namespace {

constexpr std::uint8_t kBackground = 24;  // the CLI's background grey

// .spc bytes from bytes-like data or a path, and the label messages about them start with.
std::vector<std::uint8_t> spc_bytes(const SpcData& data, std::string& label) {
  if (py::isinstance<py::bytes>(data) || py::isinstance<py::bytearray>(data) || py::isinstance<py::memoryview>(data)) {
    const std::string s = py::bytes(data);
    label = "spc bytes";
    return {s.begin(), s.end()};
  }
  const std::filesystem::path p = existing_file(data);
  label = p.string();
  return codec::read_spc_file(p);
}

// (srgb8, linear) arrays of a size x size rendering as `specula render` writes its PNG and EXR: linear RGB as
// rendered, sRGB-encoded after `exposure` stops of gain, pixels off the sphere the background grey (linear 0).
py::tuple picture(std::vector<float>&& linear, const std::vector<std::uint8_t>& covered, std::size_t size,
                  double exposure) {
  std::vector<std::uint8_t> srgb(3 * size * size);
  encode_srgb8(linear, covered, exposure, srgb, kBackground);
  const std::vector<py::ssize_t> shape{py::ssize_t(size), py::ssize_t(size), 3};
  return py::make_tuple(adopt(std::move(srgb), shape), adopt(std::move(linear), shape));
}

Eigen::Vector3d light_direction(const std::pair<double, double>& light) {
  const auto [theta, phi] = light;
  if (!(theta >= 0 && theta < 90) || !std::isfinite(phi))
    throw UsageError("render_sphere: light = (theta, phi) in degrees with 0 <= theta < 90 (angle from the viewer)");
  const double t = theta * std::numbers::pi / 180, p = phi * std::numbers::pi / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

py::tuple render(const BrdfArg& brdf, const std::pair<double, double>& light, const EnvArg& env_arg, std::size_t size,
                 const IlluminantArg& illuminant, double exposure) {
  if (!(std::abs(exposure) <= 64)) throw UsageError("render_sphere: exposure must be between -64 and 64 stops");
  const codec::SpcBrdf* spc = py::isinstance<codec::SpcBrdf>(brdf) ? &brdf.cast<const codec::SpcBrdf&>() : nullptr;
  const store::Grid* grid = py::isinstance<store::Grid>(brdf) ? &brdf.cast<const store::Grid&>() : nullptr;
  if (!env_arg.is_none()) {
    if (!spc && !grid)
      throw py::type_error(
          "render_sphere: under an environment, brdf must be a specula.Grid or specula.SpcBrdf (uplift "
          "an RGB MERL BRDF to a spectral grid first)");
    const codec::Environment env = environment_from(env_arg, spc ? spc->wavelengths() : grid->wavelengths);
    codec::SphereRenders r;
    {
      py::gil_scoped_release release;
      if (spc) {
        const codec::SpcBrdf* brdfs[] = {spc};
        r = codec::render_spheres(brdfs, env, size);
      } else {
        r = codec::render_spheres({grid}, env, size);
      }
    }
    return picture(codec::linear_srgb(r, env.description).linear, r.covered, size, exposure);
  }
  const Eigen::Vector3d dir = light_direction(light);
  auto weights = [&](const WavelengthGrid& wavelengths) {
    const Eigen::VectorXd spd = py::isinstance<py::str>(illuminant)
                                    ? parse_illuminant(illuminant.cast<std::string>(), wavelengths)
                                    : vector_from(illuminant, "render_sphere illuminant");
    if (std::size_t(spd.size()) != wavelengths.size())
      throw UsageError(
          fmt::format("render_sphere: illuminant has {} values for {} wavelengths", spd.size(), wavelengths.size()));
    return codec::rgb_weights(wavelengths, spd);
  };
  codec::SphereImage img;
  if (spc) {
    const auto w = weights(spc->wavelengths());
    py::gil_scoped_release release;
    img = codec::render_sphere(*spc, w, size, dir);
  } else if (grid) {
    const auto w = weights(grid->wavelengths);
    py::gil_scoped_release release;
    img = codec::render_sphere(codec::grid_to_merl(*grid, w).brdf, size, dir);
  } else {
    const auto v = DoubleArray::ensure(brdf);
    if (!v || v.size() != py::ssize_t(3 * brdf::kMerlCells))
      throw py::type_error(
          "render_sphere: brdf must be a specula.Grid, a specula.SpcBrdf or a MERL array (3, 90, 90, "
          "180) of stored values as read_merl gives");
    codec::MerlBrdf merl;
    merl.raw.assign(v.data(), v.data() + v.size());
    py::gil_scoped_release release;
    img = codec::render_sphere(merl, size, dir);
  }
  return picture(std::move(img.linear), img.covered, size, exposure);
}

// Direction arrays (..., 3) as float32 rows and their leading shape.
FloatArray directions(const py::object& a, const char* name, std::vector<py::ssize_t>& lead) {
  auto arr = FloatArray::ensure(a);
  if (!arr || arr.ndim() < 1 || arr.shape(arr.ndim() - 1) != 3)
    throw UsageError(
        fmt::format("SpcBrdf.evaluate: {} must be an array of directions (..., 3): x y z in the local "
                    "frame, z the normal",
                    name));
  lead.assign(arr.shape(), arr.shape() + arr.ndim() - 1);
  return arr;
}

// `out=` of SpcBrdf.evaluate: a writable, C-contiguous float32 array of exactly `shape`, as numpy's out= wants.
py::array output_array(const py::object& out, const std::vector<py::ssize_t>& shape) {
  const auto want = [&] {
    std::string s = "(";
    for (std::size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
    return s + (shape.size() == 1 ? ",)" : ")");
  };
  if (!py::isinstance<py::array>(out))
    throw UsageError("SpcBrdf.evaluate: out must be a numpy array of float32 " + want() + ", or None");
  auto arr = py::reinterpret_borrow<py::array>(out);
  if (!arr.dtype().equal(py::dtype::of<float>()))
    throw UsageError("SpcBrdf.evaluate: out has dtype " + std::string(py::str(arr.dtype())) +
                     "; give a float32 array " + want());
  if (std::vector<py::ssize_t>(arr.shape(), arr.shape() + arr.ndim()) != shape)
    throw UsageError("SpcBrdf.evaluate: out has shape " + std::string(py::str(py::tuple(out.attr("shape")))) +
                     "; give " + want() + " (the directions' shape with bands last)");
  if (!(arr.flags() & py::array::c_style) || !arr.writeable())
    throw UsageError("SpcBrdf.evaluate: out must be writable and C-contiguous (numpy.empty(shape, numpy.float32))");
  return arr;
}

}  // namespace

codec::Environment environment_from(const py::handle& env, const WavelengthGrid& grid) {
  if (py::isinstance<py::str>(env) && env.cast<std::string>() == "default") return codec::default_environment(grid);
  return codec::read_environment(existing_file(env), grid);
}

void init_render(py::module_& m) {
  py::class_<codec::SpcBrdf>(
      m, "SpcBrdf",
      "A .spc held in coefficient form (k floats per MERL cell) and evaluated at direction pairs "
      "without decoding it to a grid, in the cell MERL's BRDFRead.cpp reads.")
      .def(py::init([](const SpcData& data) {
             std::string label;
             const std::vector<std::uint8_t> bytes = spc_bytes(data, label);
             py::gil_scoped_release release;
             return std::make_unique<codec::SpcBrdf>(codec::decode_spc_coefficients(bytes, label));
           }),
           py::arg("data"), "From .spc bytes or the path of a .spc file (every field and the CRC checked).")
      .def_property_readonly("k", &codec::SpcBrdf::k, "Coefficients per cell.")
      .def_property_readonly("bands", &codec::SpcBrdf::bands)
      .def_property_readonly("wavelengths", [](const codec::SpcBrdf& b) { return wavelengths_array(b.wavelengths()); })
      .def_property_readonly("source", &codec::SpcBrdf::source, "The coded grid's source, as the file records it.")
      .def_property_readonly("reference", &codec::SpcBrdf::reference, "The basis reference the file records.")
      .def_property_readonly("memory_bytes", &codec::SpcBrdf::memory_bytes)
      .def(
          "evaluate",
          [](const codec::SpcBrdf& b, const ArrayLike& wi_arg, const ArrayLike& wo_arg,
             const OptArray& out_arg) -> Float32Result {
            std::vector<py::ssize_t> lead, lead_o;
            const FloatArray wi = directions(wi_arg, "wi", lead), wo = directions(wo_arg, "wo", lead_o);
            if (lead != lead_o) throw UsageError("SpcBrdf.evaluate: wi and wo must have the same shape");
            const std::size_t n = std::size_t(wi.size() / 3);
            lead.push_back(py::ssize_t(b.bands()));
            if (!out_arg.is_none()) {
              py::array out = output_array(out_arg, lead);
              const auto* first = static_cast<const char*>(out.data());
              for (const FloatArray* in : {&wi, &wo}) {
                const auto* p = reinterpret_cast<const char*>(in->data());
                if (p < first + out.nbytes() && first < p + in->nbytes())
                  throw UsageError("SpcBrdf.evaluate: out shares memory with wi or wo; give a separate array");
              }
              {
                py::gil_scoped_release release;
                b.evaluate(std::span(wi.data(), n * 3), std::span(wo.data(), n * 3),
                           std::span(static_cast<float*>(out.mutable_data()), n * b.bands()));
              }
              return Float32Result(std::move(out));
            }
            // Sized unwritten and on 2 MB pages when large: the evaluating threads write every value, and a fresh
            // 4 KB page costs more than the evaluations written to it.
            Buffer<float> out(n * b.bands());
            {
              py::gil_scoped_release release;
              b.evaluate(std::span(wi.data(), n * 3), std::span(wo.data(), n * 3), out);
            }
            return Float32Result(adopt(std::move(out), lead));
          },
          py::arg("wi"), py::arg("wo"), py::arg("out") = py::none(),
          "The BRDF (1/sr) at direction pairs wi, wo (..., 3) (local frame, z the normal, any length): float32 "
          "(..., bands), 0 where the cell holds no data. With out (a writable, C-contiguous float32 array of that "
          "shape) the values are written there and out is returned, so repeated calls allocate nothing.")
      .def("__repr__", [](const codec::SpcBrdf& b) {
        return fmt::format("<specula.SpcBrdf k={} {} reference='{}'>", b.k(), b.wavelengths().describe(),
                           b.reference());
      });

  m.def(
      "render_sphere", &render, py::arg("brdf"), py::arg("light") = std::pair<double, double>(45.0, 135.0),
      py::arg("env") = py::none(), py::arg("size") = 256, py::arg("illuminant") = "D65", py::arg("exposure") = 0.0,
      "A sphere as `specula render` draws it, as arrays: (srgb uint8 (size, size, 3), linear float32 (size, size, 3)). "
      "brdf: a specula.Grid, a specula.SpcBrdf (evaluated from its coefficients) or a MERL array (3, 90, 90, 180) as "
      "read_merl gives. Without env: one directional light from `light` = (theta, phi) degrees (theta from the "
      "viewer), spectral BRDFs taken to RGB under `illuminant` (a name as the CLI takes, or an SPD). With env "
      "('default' or a lat-long EXR): the spectral rendering under that environment, its white mapped to 1. sRGB "
      "after `exposure` stops; pixels off the sphere are grey 24 (linear 0).");
}

}  // namespace specula::python
