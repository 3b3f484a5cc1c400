// BRDF grids (specula.Grid), their .spgrid and .spc files, MERL .binary files, vectorised lookup at standard angles,
// and spectra -> XYZ -> sRGB.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <limits>

#include "python/common.h"
#include "specula/codec/environment.h"
#include "specula/codec/merl.h"
#include "specula/codec/nbrdf.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_coding.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/suite.h"
#include "specula/codec/uplift.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/cie.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "specula/core/preview.h"

namespace specula::python {
namespace {

constexpr py::ssize_t kDims[3] = {brdf::kMerlThetaH, brdf::kMerlThetaD, brdf::kMerlPhiD};

// The grid's values as a read-only (bands, 90, 90, 180) float32 view that keeps the Grid alive.
py::array grid_values(py::object self) {
  auto& g = self.cast<store::Grid&>();
  return readonly(py::array_t<float>({py::ssize_t(g.bands()), kDims[0], kDims[1], kDims[2]}, g.brdf.data(), self));
}

// A grid from wavelengths and (bands, 90, 90, 180) values.
store::Grid make_grid(const py::handle& wavelengths, const py::handle& values, double scale, const std::string& units) {
  store::Grid g;
  g.wavelengths = grid_from(wavelengths, "Grid wavelengths");
  const auto v = FloatArray::ensure(values);
  if (!v || v.ndim() != 4 || std::size_t(v.shape(0)) != g.bands() || v.shape(1) != kDims[0] || v.shape(2) != kDims[1] ||
      v.shape(3) != kDims[2])
    throw UsageError(fmt::format("Grid: values must be ({}, 90, 90, 180)", g.bands()));
  g.brdf.assign(v.data(), v.data() + v.size());
  g.scale = scale;
  g.units = units;
  return g;
}

Observer parse_observer(const std::string& s) {
  if (s == "cie1931_2deg" || s == "1931") return Observer::cie1931_2deg;
  if (s == "cie1964_10deg" || s == "1964") return Observer::cie1964_10deg;
  throw UsageError(fmt::format("observer '{}': give cie1931_2deg or cie1964_10deg", s));
}

SpectrumKind parse_kind(const std::string& s) {
  if (s == "reflectance") return SpectrumKind::reflectance;
  if (s == "radiance") return SpectrumKind::radiance;
  throw UsageError(fmt::format("kind '{}': give reflectance or radiance", s));
}

Eigen::VectorXd illuminant_from(const IlluminantArg& ill, const WavelengthGrid& grid) {
  if (py::isinstance<py::str>(ill)) return parse_illuminant(ill.cast<std::string>(), grid);
  Eigen::VectorXd v = vector_from(ill, "illuminant");
  if (std::size_t(v.size()) != grid.size())
    throw UsageError(fmt::format("illuminant: {} values for {} wavelengths", v.size(), grid.size()));
  return v;
}

// Spectra (..., B) as float64 rows and their leading shape; UsageError unless the last axis has `bands` entries.
DoubleArray spectra_rows(const py::object& a, std::size_t bands, std::vector<py::ssize_t>& lead, const char* fn) {
  auto arr = DoubleArray::ensure(a);
  if (!arr || arr.ndim() < 1 || std::size_t(arr.shape(arr.ndim() - 1)) != bands)
    throw UsageError(fmt::format("{}: spectra must be an array whose last axis has the {} wavelengths", fn, bands));
  lead.assign(arr.shape(), arr.shape() + arr.ndim() - 1);
  return arr;
}

// XYZ rows -> (sRGB8, linear RGB) through core's display pipeline.
py::tuple display(const Eigen::Ref<const RowMatrixX3f>& xyz, const std::vector<py::ssize_t>& lead,
                  const Eigen::Vector3d& white, const DisplayOptions& o) {
  const Eigen::Index n = xyz.rows();
  std::vector<std::uint8_t> srgb(std::size_t(n) * 3);
  std::vector<float> linear(std::size_t(n) * 3);
  {
    py::gil_scoped_release release;
    xyz_to_display(xyz, white, o, Eigen::Map<RowMatrixX3f>(linear.data(), n, 3), srgb);
  }
  std::vector<py::ssize_t> shape = lead;
  shape.push_back(3);
  return py::make_tuple(adopt(std::move(srgb), shape), adopt(std::move(linear), shape));
}

// specula.spc_encode: `specula encode` on a grid in memory (see its docstring below).
py::tuple spc_encode(const GridArg& grid_arg, const OptBasis& basis_arg, std::optional<std::size_t> k,
                     std::size_t extra, double max_error, double magnitude_scale, int zstd_level,
                     const OptStr& reference, std::optional<double> step, std::optional<double> target_de00,
                     std::optional<double> target_p95, int trials, const EnvArg& env_arg) {
  const store::Grid& grid = as<store::Grid>(grid_arg, "spc_encode", "grid", "Grid");
  if (step && target_de00) throw UsageError("spc_encode: give step or target_de00, not both");
  if (target_p95 && !target_de00) throw UsageError("spc_encode: target_p95 goes with target_de00");
  std::optional<store::Basis> basis;
  std::string ref;
  if (!basis_arg.is_none()) {
    basis = as<store::Basis>(basis_arg, "spc_encode", "basis", "Basis");
    if (!reference.is_none())
      ref = reference.cast<std::string>();
    else if (py::hasattr(basis_arg, "_origin"))
      ref = basis_arg.attr("_origin").cast<std::string>();
    else
      ref = basis->source.empty() ? "python" : basis->source;
  } else if (!reference.is_none()) {
    throw UsageError("spc_encode: reference names a learned basis; without one the basis is 'self'");
  }
  const codec::SpcBoundedOptions bounded{
      .max_error = max_error, .magnitude_scale = magnitude_scale, .zstd_level = zstd_level};
  codec::SpcTransformOptions options{.magnitude_scale = magnitude_scale};
  if (step) options.step = *step;
  const bool transform = step || target_de00;
  const codec::SpcTarget t{.de00_mean = target_de00.value_or(0),
                           .de00_p95 = target_p95.value_or(codec::default_p95_target(target_de00.value_or(0))),
                           .condition_mean = codec::condition_mean_target(target_de00.value_or(0)),
                           .max_trials = trials};
  std::optional<codec::LightingSuite> suite;
  if (target_de00) suite.emplace(environment_from(env_arg, grid.wavelengths), codec::SuiteOptions{});
  if (!basis && extra) throw UsageError("spc_encode: extra extends a learned basis; with no basis raise k instead");
  const codec::SpcBasisSource source{
      .learned = basis ? std::make_shared<const store::Basis>(*basis) : nullptr, .reference = ref, .extra = extra};
  const std::size_t kk = k ? *k : target_de00 ? 0 : 6;  // no k: the target chooses it, else 6
  codec::SpcCoding coding;
  const auto t0 = std::chrono::steady_clock::now();
  {
    py::gil_scoped_release release;
    const std::string& label = grid.provenance.source_file;
    if (suite) {
      const codec::SpcTargetSearch search{t, *suite};
      coding = codec::code_grid(grid, source, kk, options, &search, label);
    } else {
      coding = transform ? codec::code_grid(grid, source, kk, options, nullptr, label)
                         : codec::code_grid(grid, source, kk, bounded, label);
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto report =
      codec::spc_coding_json(coding, transform ? nullptr : &bounded, target_de00 ? &t : nullptr, seconds, "spc_encode");
  return py::make_tuple(py::bytes(reinterpret_cast<const char*>(coding.bytes.data()), coding.bytes.size()),
                        py::module_::import("json").attr("loads")(report.dump()));
}

// The Grid class and its exchange files.
void def_grid(py::module_& m) {
  py::class_<store::Grid>(
      m, "Grid",
      "A spectral BRDF on the MERL grid: values (bands, 90 theta_h, 90 theta_d, 180 phi_d) float32; "
      "value * scale is in 1/sr; a negative value means no data.")
      .def(py::init(&make_grid), py::arg("wavelengths"), py::arg("values"), py::arg("scale") = 1.0,
           py::arg("units") = "1/sr")
      .def_property_readonly("values", &grid_values)
      .def_property_readonly("wavelengths", [](const store::Grid& g) { return wavelengths_array(g.wavelengths); })
      .def_property_readonly("bands", &store::Grid::bands)
      .def_readwrite("scale", &store::Grid::scale)
      .def_readonly("units", &store::Grid::units)
      .def_property_readonly(
          "source", [](const store::Grid& g) { return g.provenance.source_file; },
          "What the grid was made from, as its provenance records it.")
      .def(py::pickle(
          [](const store::Grid& g) {
            const auto& p = g.provenance;
            return py::make_tuple(
                wavelengths_array(g.wavelengths),
                py::array_t<float>({py::ssize_t(g.bands()), kDims[0], kDims[1], kDims[2]}, g.brdf.data()), g.scale,
                g.units, py::make_tuple(p.source_file, p.importer, p.command_line, p.created_utc));
          },
          [](const py::tuple& t) {
            if (t.size() != 5) throw UsageError("Grid: not a pickled specula.Grid");
            store::Grid g = make_grid(t[0], t[1], t[2].cast<double>(), t[3].cast<std::string>());
            const auto p = t[4].cast<py::tuple>();
            g.provenance = {p[0].cast<std::string>(), p[1].cast<std::string>(), p[2].cast<std::string>(),
                            p[3].cast<std::string>()};
            return g;
          }))
      .def("__repr__", [](const store::Grid& g) {
        return fmt::format("<specula.Grid {} scale={}>", g.wavelengths.describe(), g.scale);
      });

  m.def(
      "read_spgrid", [](const PathArg& p) { return codec::read_grid_file(existing_file(p)); }, py::arg("path"),
      "Reads a grid exchange file (.spgrid, docs/grid-format.md).");
  m.def(
      "write_spgrid",
      [](const PathArg& p, const GridArg& grid) {
        const store::Grid& g = as<store::Grid>(grid, "write_spgrid", "grid", "Grid");
        const std::filesystem::path path = path_from(p);
        py::gil_scoped_release release;
        codec::write_grid_file(path, g);
      },
      py::arg("path"), py::arg("grid"), "Writes a grid exchange file (complete or not at all).");
}

// MERL .binary files.
void def_merl(py::module_& m) {
  m.attr("MERL_SCALE") = py::make_tuple(codec::kMerlScale[0], codec::kMerlScale[1], codec::kMerlScale[2]);
  m.def(
      "read_merl",
      [](const PathArg& p, bool scaled) {
        codec::MerlBrdf b = codec::read_merl(existing_file(p));
        if (scaled) b.scale();
        return adopt(std::move(b.raw), {3, kDims[0], kDims[1], kDims[2]});
      },
      py::arg("path"), py::arg("scaled") = false,
      "A MERL .binary as (3, 90, 90, 180) float64: the stored values (negative: no data), or with scaled=True the "
      "BRDF in 1/sr (stored value times MERL_SCALE; no-data cells keep their negative value).");
  m.def(
      "write_merl",
      [](const PathArg& p, const ArrayLike& values, bool scaled) {
        const auto v = DoubleArray::ensure(values);
        if (!v || v.size() != py::ssize_t(3 * brdf::kMerlCells))
          throw UsageError("write_merl: values must be (3, 90, 90, 180)");
        codec::MerlBrdf b;
        b.raw.assign(v.data(), v.data() + v.size());
        if (scaled) b.unscale();
        const std::filesystem::path path = path_from(p);
        py::gil_scoped_release release;
        codec::write_merl(path, b);
      },
      py::arg("path"), py::arg("values"), py::arg("scaled") = false,
      "Writes (3, 90, 90, 180) values as a MERL .binary (stored values, or 1/sr with scaled=True).");
  m.def(
      "read_nbrdf",
      [](const PathArg& p, bool scaled) {
        const std::filesystem::path path = existing_file(p);
        codec::MerlBrdf b;
        {
          py::gil_scoped_release release;
          b = codec::nbrdf_to_merl(store::read_nbrdf(path));
        }
        if (scaled) b.scale();
        return adopt(std::move(b.raw), {3, kDims[0], kDims[1], kDims[2]});
      },
      py::arg("path"), py::arg("scaled") = false,
      "A neural BRDF (Sztrajman et al. 2021, Keras HDF5 weights) evaluated at every MERL cell centre as `specula "
      "import "
      "X.h5 --format nbrdf -o X.binary` does: (3, 90, 90, 180) float64 as read_merl gives it (negative: below the "
      "horizon; scaled=True: 1/sr). InputError naming the file for weights of the wrong shapes or not finite.");
  m.def(
      "uplift",
      [](const ArrayLike& values, bool scaled, const WavelengthsArg& wavelengths, const IlluminantArg& ill,
         double alpha, bool nonnegative) {
        const auto v = DoubleArray::ensure(values);
        if (!v || v.size() != py::ssize_t(3 * brdf::kMerlCells))
          throw UsageError("uplift: values must be (3, 90, 90, 180) as read_merl or read_nbrdf give them");
        if (!(alpha > 0) || !std::isfinite(alpha))
          throw UsageError(fmt::format("uplift: alpha = {}: give a positive weight", alpha));
        const WavelengthGrid grid = grid_from(wavelengths, "uplift wavelengths");
        const codec::Uplift uplift(codec::rgb_weights(grid, illuminant_from(ill, grid)), alpha);
        codec::MerlBrdf rgb;
        rgb.raw.assign(v.data(), v.data() + v.size());
        if (scaled) rgb.unscale();
        store::Grid g;
        {
          py::gil_scoped_release release;
          g = codec::uplift_merl(rgb, grid, uplift,
                                 nonnegative ? codec::UpliftMethod::nonnegative : codec::UpliftMethod::clamp);
        }
        g.provenance.importer = nonnegative ? "uplift-nonnegative" : "uplift-clamp";
        g.provenance.command_line = python_command_line("uplift");
        return g;
      },
      py::arg("values"), py::arg("scaled") = false, py::kw_only(), py::arg("wavelengths") = "400:700:10",
      py::arg("illuminant") = "D65", py::arg("alpha") = codec::kDefaultUpliftAlpha, py::arg("nonnegative") = false,
      "An RGB BRDF (3, 90, 90, 180) as read_merl or read_nbrdf give it (stored values, or 1/sr with scaled=True; "
      "negative: no data) as a "
      "spectral Grid in 1/sr on `wavelengths`, cell by cell by the regularised least squares of the reference's eq A.3 "
      "(Appendix A) under `illuminant` with weight `alpha`, then clamped to 0, or with nonnegative=True bounded to "
      "x >= 0 (what `specula import X.h5 --uplift` does to a neural BRDF): `specula uplift`.");
}

// Standard angles to MERL cells and grid values.
void def_lookup(py::module_& m) {
  m.def(
      "merl_index",
      [](const ArrayLike& ti, const ArrayLike& pi, const ArrayLike& to, const ArrayLike& po) {
        const auto a = DoubleArray::ensure(ti), b = DoubleArray::ensure(pi), c = DoubleArray::ensure(to),
                   d = DoubleArray::ensure(po);
        if (!a || !b || !c || !d || a.size() != b.size() || a.size() != c.size() || a.size() != d.size())
          throw UsageError("merl_index: theta_i, phi_i, theta_o, phi_o must be arrays of one size");
        py::array_t<std::int64_t> out(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
        std::int64_t* o = out.mutable_data();
        const py::ssize_t n = a.size();
        {
          py::gil_scoped_release release;
          for (py::ssize_t i = 0; i < n; ++i) {
            const brdf::StdAngles s{a.data()[i], b.data()[i], c.data()[i], d.data()[i]};
            if (!std::isfinite(s.theta_i) || !std::isfinite(s.phi_i) || !std::isfinite(s.theta_o) ||
                !std::isfinite(s.phi_o))
              throw UsageError(fmt::format("merl_index: angles of entry {} are not finite", i));
            o[i] = std::int64_t(brdf::merl_index(brdf::merl_cell(s)));
          }
        }
        return out;
      },
      py::arg("theta_i"), py::arg("phi_i"), py::arg("theta_o"), py::arg("phi_o"),
      "The MERL cell (linear index, phi_d fastest) that BRDFRead.cpp reads for each set of standard angles (radians).");
  m.def(
      "brdf_lookup",
      [](const GridArg& grid, const ArrayLike& ti, const ArrayLike& pi, const ArrayLike& to, const ArrayLike& po) {
        const store::Grid& g = as<store::Grid>(grid, "brdf_lookup", "grid", "Grid");
        const auto a = DoubleArray::ensure(ti), b = DoubleArray::ensure(pi), c = DoubleArray::ensure(to),
                   d = DoubleArray::ensure(po);
        if (!a || !b || !c || !d || a.size() != b.size() || a.size() != c.size() || a.size() != d.size())
          throw UsageError("brdf_lookup: theta_i, phi_i, theta_o, phi_o must be arrays of one size");
        std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
        shape.push_back(py::ssize_t(g.bands()));
        const py::ssize_t n = a.size();
        const std::size_t bands = g.bands();
        std::vector<double> out(std::size_t(n) * bands);
        {
          py::gil_scoped_release release;
          for (py::ssize_t i = 0; i < n; ++i) {
            const brdf::StdAngles s{a.data()[i], b.data()[i], c.data()[i], d.data()[i]};
            if (!std::isfinite(s.theta_i) || !std::isfinite(s.phi_i) || !std::isfinite(s.theta_o) ||
                !std::isfinite(s.phi_o))
              throw UsageError(fmt::format("brdf_lookup: angles of entry {} are not finite", i));
            const std::size_t cell = brdf::merl_index(brdf::merl_cell(s));
            for (std::size_t k = 0; k < bands; ++k) {
              const float v = g.brdf[k * brdf::kMerlCells + cell];
              out[std::size_t(i) * bands + k] = v < 0 ? std::numeric_limits<double>::quiet_NaN() : double(v) * g.scale;
            }
          }
        }
        return as_dtype(adopt(std::move(out), shape), is_float32(ti));
      },
      py::arg("grid"), py::arg("theta_i"), py::arg("phi_i"), py::arg("theta_o"), py::arg("phi_o"),
      "The grid's BRDF (1/sr) at arrays of standard angles (radians), in the cell BRDFRead.cpp reads: shape of the "
      "angles + (bands,), NaN where the cell holds no data; float32 angles give float32 values.");
}

// .spc files: encoding, decoding, writing.
void def_spc(py::module_& m) {
  m.def("spc_encode", &spc_encode, py::arg("grid"), py::arg("basis") = py::none(), py::arg("k") = py::none(),
        py::arg("extra") = 0, py::arg("max_error") = 0.01, py::arg("magnitude_scale") = 0.0, py::arg("zstd_level") = 9,
        py::arg("reference") = py::none(), py::arg("step") = py::none(), py::arg("target_de00") = py::none(),
        py::arg("target_p95") = py::none(), py::arg("trials") = 8, py::arg("env") = "default",
        "Encodes a grid as .spc bytes (docs/codec-format.md) as `specula encode` does: on a learned basis (its first k "
        "as coding_basis takes them, plus `extra` fitted spectra) or, without one, on the grid's own top-k basis (k "
        "None: with target_de00 the k of the smallest file meeting the target, reported in 'k_search'; else 6); "
        "bounded (format 1, max_error), or transform (format 2) with a quantisation `step` or the coarsest step whose "
        "rendering under `env` ('default' or a lat-long EXR) has CIEDE2000 mean at most target_de00 (and 95th "
        "percentile at most target_p95, default 3x). `reference` (recorded in the file) defaults to where the basis "
        "came from ('STORE.h5:NAME' for a basis read from or saved in a store). Returns (bytes, report), the report "
        "with the fields of `specula encode --json`.");
  m.def(
      "spc_decode",
      [](const SpcData& data) {
        std::vector<std::uint8_t> bytes;
        std::string label = "spc bytes";
        if (py::isinstance<py::bytes>(data) || py::isinstance<py::bytearray>(data) ||
            py::isinstance<py::memoryview>(data)) {
          const std::string s = py::bytes(data);
          bytes.assign(s.begin(), s.end());
        } else {
          const std::filesystem::path p = existing_file(data);
          bytes = codec::read_spc_file(p);
          label = p.string();
        }
        py::gil_scoped_release release;
        return codec::decode_spc(bytes, label);
      },
      py::arg("data"),
      "Decodes .spc bytes, or the .spc file at a path, into a Grid (every field and the CRC checked).");
  m.def(
      "write_spc",
      [](const PathArg& p, const py::bytes& data) {
        const std::string s = data;
        codec::write_spc_file(path_from(p), std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()));
      },
      py::arg("path"), py::arg("data"), "Writes .spc bytes to a file (complete or not at all).");
}

// Colour matching functions, illuminants and XYZ weights.
void def_colour(py::module_& m) {
  m.def(
      "cmf",
      [](const WavelengthsArg& w, const std::string& observer) {
        return to_numpy(Eigen::MatrixXd(cmf(grid_from(w, "wavelengths"), parse_observer(observer))));
      },
      py::arg("wavelengths"), py::arg("observer") = "cie1931_2deg",
      "The CIE colour-matching functions at the wavelengths, (bands, 3): xbar, ybar, zbar.");
  m.def(
      "illuminant",
      [](const std::string& name, const WavelengthsArg& w) {
        return to_numpy(Eigen::VectorXd(parse_illuminant(name, grid_from(w, "wavelengths"))));
      },
      py::arg("name"), py::arg("wavelengths"),
      "The relative SPD at the wavelengths of an illuminant named as the CLI names it: D65, D50, A, E, D<CCT/100> "
      "(e.g. D75), blackbody:K or an SPD CSV file.");
  m.def(
      "xyz_weights",
      [](const WavelengthsArg& w, const std::string& kind, const IlluminantArg& ill, const std::string& observer) {
        const WavelengthGrid grid = grid_from(w, "wavelengths");
        const SpectrumToXyz t(grid, parse_kind(kind), illuminant_from(ill, grid), parse_observer(observer));
        return py::make_tuple(to_numpy(Eigen::MatrixXd(t.weights())), to_numpy(Eigen::VectorXd(t.white())));
      },
      py::arg("wavelengths"), py::arg("kind") = "reflectance", py::arg("illuminant") = "D65",
      py::arg("observer") = "cie1931_2deg", "(W, white): XYZ = W @ spectrum (W is 3 x bands) and the scene white.");
}

// Spectra to XYZ and XYZ to display sRGB.
void def_display(py::module_& m) {
  m.def(
      "spectra_to_xyz",
      [](const ArrayLike& spectra, const WavelengthsArg& w, const std::string& kind, const IlluminantArg& ill,
         const std::string& observer) {
        const WavelengthGrid grid = grid_from(w, "wavelengths");
        const SpectrumToXyz t(grid, parse_kind(kind), illuminant_from(ill, grid), parse_observer(observer));
        std::vector<py::ssize_t> lead;
        const auto x = spectra_rows(spectra, grid.size(), lead, "spectra_to_xyz");
        const Eigen::Index n = x.size() / Eigen::Index(grid.size());
        std::vector<double> out(std::size_t(n) * 3);
        {
          py::gil_scoped_release release;
          Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(out.data(), n, 3).noalias() =
              Eigen::Map<const RowMatrixXd>(x.data(), n, Eigen::Index(grid.size())) * t.weights().transpose();
        }
        lead.push_back(3);
        return adopt(std::move(out), lead);
      },
      py::arg("spectra"), py::arg("wavelengths"), py::arg("kind") = "reflectance", py::arg("illuminant") = "D65",
      py::arg("observer") = "cie1931_2deg",
      "CIE XYZ of spectra (..., bands) by trapezoid quadrature of the CMFs: reflectance lit by the illuminant (a "
      "perfect white has Y = 1) or radiance (a flat spectrum of 1 has Y = 1).");
  m.def(
      "xyz_to_srgb",
      [](const ArrayLike& xyz, const OptArray& white, double exposure, const std::string& tone, bool adapt,
         bool desaturate) {
        std::vector<py::ssize_t> lead;
        const auto x = spectra_rows(xyz, 3, lead, "xyz_to_srgb");
        const Eigen::Index n = x.size() / 3;
        const RowMatrixX3f xf =
            Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(x.data(), n, 3).cast<float>();
        Eigen::Vector3d w(0.95047, 1.0, 1.08883);
        if (!white.is_none()) {
          const Eigen::VectorXd v = vector_from(white, "white");
          if (v.size() != 3) throw UsageError("xyz_to_srgb: white must be 3 values (XYZ)");
          w = v;
        }
        return display(xf, lead, w,
                       {.exposure_stops = exposure,
                        .tone = specula::parse_tone(tone),
                        .adapt_to_d65 = adapt,
                        .desaturate = desaturate});
      },
      py::arg("xyz"), py::arg("white") = py::none(), py::arg("exposure") = 0.0, py::arg("tone") = "clip",
      py::arg("adapt") = true, py::arg("desaturate") = true,
      "Display sRGB of XYZ (..., 3): exposure in stops, tone map, Bradford adaptation from `white` (default D65's "
      "XYZ), gamut mapping by desaturation. Returns (srgb8 uint8, linear float32), both (..., 3).");
  m.def(
      "spectra_to_srgb",
      [](const ArrayLike& spectra, const WavelengthsArg& w, const std::string& kind, const IlluminantArg& ill,
         double exposure, const std::string& tone, bool adapt, bool desaturate) {
        const WavelengthGrid grid = grid_from(w, "wavelengths");
        const SpectrumToXyz t(grid, parse_kind(kind), illuminant_from(ill, grid));
        std::vector<py::ssize_t> lead;
        const auto x = spectra_rows(spectra, grid.size(), lead, "spectra_to_srgb");
        const Eigen::Index n = x.size() / Eigen::Index(grid.size());
        RowMatrixX3f xyz(n, 3);
        {
          py::gil_scoped_release release;
          const RowMatrixXf xf = Eigen::Map<const RowMatrixXd>(x.data(), n, Eigen::Index(grid.size())).cast<float>();
          t.apply(xf, xyz);
        }
        return display(xyz, lead, t.white(),
                       {.exposure_stops = exposure,
                        .tone = specula::parse_tone(tone),
                        .adapt_to_d65 = adapt,
                        .desaturate = desaturate});
      },
      py::arg("spectra"), py::arg("wavelengths"), py::arg("kind") = "reflectance", py::arg("illuminant") = "D65",
      py::arg("exposure") = 0.0, py::arg("tone") = "clip", py::arg("adapt") = true, py::arg("desaturate") = true,
      "Display sRGB of spectra (..., bands): spectra_to_xyz then xyz_to_srgb with the scene white. Returns (srgb8, "
      "linear).");
}

}  // namespace

void init_brdf(py::module_& m) {
  def_grid(m);
  def_merl(m);
  def_lookup(m);
  def_spc(m);
  def_colour(m);
  def_display(m);
}

}  // namespace specula::python
