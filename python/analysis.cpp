// specula.Basis, pca(), nmf() and project(): the calls apps/cmd_pca.cpp, cmd_nmf.cpp and cmd_project.cpp make,
// with the GIL released while they stream, returning numpy results and optionally saving the basis as the CLI does.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "python/common.h"
#include "specula/core/error.h"
#include "specula/nmf/learn.h"
#include "specula/nmf/report.h"
#include "specula/stats/learn_pca.h"
#include "specula/stats/pca.h"
#include "specula/stats/project.h"
#include "specula/store/learned_basis.h"

namespace specula::python {
namespace {

// The store a basis is saved in: `output` when given, else the first input store (as the CLI's basis_output).
std::filesystem::path output_store(const std::vector<store::Store>& stores, const OptPath& output) {
  if (output.is_none()) return stores.front().path();
  return py::module_::import("os").attr("fspath")(output).cast<std::string>();
}

void save_basis_released(const std::filesystem::path& out, const std::string& name, const store::Basis& basis,
                         bool replace, const std::string& function) {
  py::gil_scoped_release release;
  try {
    store::save_basis(out, name, basis, replace, python_command_line(function));
  } catch (const InputError& e) {
    if (std::string(e.what()).find("exists already") == std::string::npos) throw;
    throw InputError(
        fmt::format("{}: basis '{}' exists already; choose another name or give replace=True", out.string(), name));
  }
  note_commit();
}

// A basis saved as `name` in the store at `path`, knowing where it lives (its `origin`, the reference .spc files
// coded on it record, as `specula encode` names it).
BasisResult with_origin(store::Basis&& b, const std::filesystem::path& path, const std::string& name) {
  BasisResult o = py::cast(std::move(b));
  o.attr("_origin") = path.filename().string() + ":" + name;
  return o;
}

// Projection of spectra (..., B) onto the first k components of a PCA basis or all of an NMF basis by the
// projector `specula project` uses (stats/project.h), with the per-spectrum L2 error, rms and max_error over the
// spectra the mask keeps.
py::dict project_one(const store::Basis& basis, const ArrayLike& spectra_arg, const py::object& k_arg,
                     const OptArray& mask_arg) {
  if (k_arg.is_none() && stats::basis_method(basis) == stats::BasisMethod::pca)
    throw UsageError("project: k is required with a PCA basis (the number of leading components, e.g. 6)");
  const stats::Projector projector(basis,
                                   k_arg.is_none() ? std::nullopt : std::optional<long long>(k_arg.cast<long long>()));
  const std::size_t k = projector.k();
  const auto spectra = DoubleArray::ensure(spectra_arg);
  if (!spectra || spectra.ndim() < 1 || std::size_t(spectra.shape(spectra.ndim() - 1)) != basis.bands())
    throw UsageError(
        fmt::format("project: spectra must be an array whose last axis has the basis's {} bands", basis.bands()));
  std::vector<py::ssize_t> lead(spectra.shape(), spectra.shape() + spectra.ndim() - 1);
  py::ssize_t n = 1;
  for (auto s : lead) n *= s;
  std::vector<std::uint8_t> mask;
  if (!mask_arg.is_none()) {
    const auto ma = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>::ensure(mask_arg);
    if (!ma || ma.size() != n) throw UsageError(fmt::format("project: mask must have one entry per spectrum ({})", n));
    mask.assign(ma.data(), ma.data() + n);
  }
  const Eigen::Index b = Eigen::Index(basis.bands());
  std::vector<double> coef(std::size_t(n) * k), recon(std::size_t(n) * std::size_t(b));
  std::vector<double> error(static_cast<std::size_t>(n));
  stats::ProjectionError summary;
  {
    py::gil_scoped_release release;
    const Eigen::Map<const RowMatrixXd> x(spectra.data(), n, b);
    Eigen::Map<RowMatrixXd> c(coef.data(), n, Eigen::Index(k));
    Eigen::Map<RowMatrixXd> xr(recon.data(), n, b);
    Eigen::Map<Eigen::VectorXd> e(error.data(), n);
    summary = stats::project_rows(projector, x, mask, c, xr, e);
  }
  std::vector<py::ssize_t> cshape = lead, rshape = lead;
  cshape.push_back(py::ssize_t(k));
  rshape.push_back(py::ssize_t(b));
  py::dict out;
  // float32 spectra give float32 results (computed in float64).
  const bool f32 = is_float32(spectra_arg);
  out["k"] = k;
  out["coefficients"] = as_dtype(adopt(std::move(coef), cshape), f32);
  out["reconstruction"] = as_dtype(adopt(std::move(recon), rshape), f32);
  out["error"] = as_dtype(adopt(std::move(error), lead), f32);
  out["rms"] = summary.rms(std::size_t(b));
  out["max_error"] = summary.max_error;
  return out;
}

// specula.Basis: a learned basis made in Python or read from a store, its arrays as numpy.
void init_basis(py::module_& m) {
  py::class_<store::Basis>(m, "Basis", py::dynamic_attr(),
                           "A learned spectral basis: components are rows (k x bands); PCA bases carry mean, "
                           "eigenvalues, explained variance, covariance; NMF bases weights.")
      .def(py::init([](const std::string& method, const WavelengthsArg& wavelengths, const ArrayLike& components,
                       const OptArray& mean, const OptArray& weights) {
             store::Basis b;
             if (method != "pca" && method != "nmf")
               throw UsageError(fmt::format("Basis: method '{}': give pca or nmf", method));
             b.method = method;
             b.wavelengths = grid_from(wavelengths, "Basis wavelengths");
             b.components = matrix_from(components, "Basis components");
             if (std::size_t(b.components.cols()) != b.bands())
               throw UsageError(
                   fmt::format("Basis: components have {} columns for {} wavelengths", b.components.cols(), b.bands()));
             if (!mean.is_none()) b.mean = vector_from(mean, "Basis mean");
             if (!weights.is_none()) b.weights = vector_from(weights, "Basis weights");
             if (method == "pca" && std::size_t(b.mean.size()) != b.bands())
               throw UsageError(fmt::format("Basis: a pca basis needs a mean of {} values", b.bands()));
             b.source = "python";
             return b;
           }),
           py::arg("method"), py::arg("wavelengths"), py::arg("components"), py::arg("mean") = py::none(),
           py::arg("weights") = py::none())
      .def_readonly("method", &store::Basis::method)
      .def_readonly("n", &store::Basis::n)
      .def_readonly("source", &store::Basis::source)
      .def_property_readonly("k", &store::Basis::k)
      .def_property_readonly("bands", &store::Basis::bands)
      .def_property_readonly("wavelengths", [](const store::Basis& b) { return wavelengths_array(b.wavelengths); })
      .def_property_readonly(
          "components", [](py::object b) { return view(b.cast<const store::Basis&>().components, b); },
          "The components as rows (k, bands): a read-only view.")
      .def_property_readonly("mean", [](py::object b) { return view(b.cast<const store::Basis&>().mean, b); })
      .def_property_readonly("eigenvalues",
                             [](py::object b) { return view(b.cast<const store::Basis&>().eigenvalues, b); })
      .def_property_readonly(
          "explained_variance_ratio",
          [](py::object b) { return view(b.cast<const store::Basis&>().explained_variance_ratio, b); })
      .def_property_readonly("covariance",
                             [](py::object b) { return view(b.cast<const store::Basis&>().covariance, b); })
      .def_property_readonly("second_moment",
                             [](py::object b) { return view(b.cast<const store::Basis&>().second_moment, b); })
      .def_property_readonly("weights", [](py::object b) { return view(b.cast<const store::Basis&>().weights, b); })
      .def(py::pickle(
          [](const py::object& self) {
            const auto& b = self.cast<const store::Basis&>();
            const auto& p = b.provenance;
            return py::make_tuple(self.attr("__dict__"), b.method, wavelengths_array(b.wavelengths), b.n,
                                  to_numpy(b.mean), to_numpy(b.components), to_numpy(b.eigenvalues),
                                  to_numpy(b.explained_variance_ratio), to_numpy(b.covariance),
                                  to_numpy(b.second_moment), to_numpy(b.weights), b.source,
                                  py::make_tuple(p.source_file, p.importer, p.command_line, p.created_utc));
          },
          [](py::tuple state) {
            if (state.size() != 13) throw UsageError("Basis: not a pickled specula.Basis");
            const py::dict attributes = state[0];
            const py::tuple t = state[py::slice(1, 13, 1)];
            store::Basis b;
            b.method = t[0].cast<std::string>();
            b.wavelengths = grid_from(t[1], "Basis wavelengths");
            b.n = t[2].cast<std::uint64_t>();
            b.mean = vector_from(t[3], "Basis mean");
            b.components = matrix_from(t[4], "Basis components");
            b.eigenvalues = vector_from(t[5], "Basis eigenvalues");
            b.explained_variance_ratio = vector_from(t[6], "Basis explained_variance_ratio");
            b.covariance = matrix_from(t[7], "Basis covariance");
            b.second_moment = matrix_from(t[8], "Basis second_moment");
            b.weights = vector_from(t[9], "Basis weights");
            b.source = t[10].cast<std::string>();
            const auto p = t[11].cast<py::tuple>();
            b.provenance = {p[0].cast<std::string>(), p[1].cast<std::string>(), p[2].cast<std::string>(),
                            p[3].cast<std::string>()};
            return std::make_pair(std::move(b), attributes);
          }))
      .def("__repr__", [](const store::Basis& b) {
        return fmt::format("<specula.Basis {} k={} {} n={}>", b.method, b.k(), b.wavelengths.describe(), b.n);
      });
}

void def_pca(py::module_& m) {
  m.def(
      "pca",
      [](const StoresArg& stores_arg, const ImagesArg& images, const std::string& collection, std::size_t k,
         const OptStr& name, const OptPath& output, bool replace) -> BasisResult {
        const std::vector<store::Store> stores = stores_from(stores_arg);
        if (!name.is_none()) store::validate_name(name.cast<std::string>(), "basis");
        const std::filesystem::path out = output_store(stores, output);
        const store::Selection sel{.image_globs = globs_from(images), .collection = collection};
        store::Basis basis = interruptible([&] { return stats::learn_pca(stores, sel, k).basis; });
        if (name.is_none()) return BasisResult(py::cast(std::move(basis)));
        save_basis_released(out, name.cast<std::string>(), basis, replace, "pca");
        return with_origin(std::move(basis), out, name.cast<std::string>());
      },
      py::arg("stores"), py::arg("images") = py::none(), py::arg("collection") = "", py::arg("k") = 0,
      py::arg("name") = py::none(), py::arg("output") = py::none(), py::arg("replace") = false,
      "PCA (reference §7.3) of every valid spectrum of the selected images (or a collection) of one or more stores, "
      "in one exact streaming pass, as `specula pca` does; k = 0 keeps every component. With `name`, the basis is "
      "also saved in `output` (default: the first store).");
}

void def_nmf(py::module_& m) {
  m.def(
      "nmf",
      [](const StoresArg& stores_arg, std::size_t k, const ImagesArg& images, const std::string& collection,
         const std::string& init, std::uint64_t seed, std::size_t restarts, std::size_t max_epochs,
         std::size_t wave_blocks, double tol, const std::string& negatives, const OptStr& name, const OptPath& output,
         const OptPath& checkpoint, bool resume, bool replace, const CallbackArg& on_epoch) {
        const std::vector<store::Store> stores = stores_from(stores_arg);
        const std::optional<std::string> save = name.is_none() ? std::nullopt : std::optional(name.cast<std::string>());
        if (save) store::validate_name(*save, "basis");
        const std::filesystem::path out = output_store(stores, output);
        nmf::NmfOptions opt{.k = k,
                            .init = nmf::parse_init(init),
                            .seed = seed,
                            .restarts = restarts,
                            .max_epochs = max_epochs,
                            .tol = tol,
                            .negatives = nmf::parse_negatives(negatives),
                            .wave_blocks = wave_blocks,
                            .resume = resume};
        if (!checkpoint.is_none())
          opt.checkpoint = py::module_::import("os").attr("fspath")(checkpoint).cast<std::string>();
        else if (save)
          opt.checkpoint = nmf::default_checkpoint(out, *save);
        if (save && !replace && !resume && store::holds_basis(out, *save))
          throw UsageError(fmt::format("{}: basis {} already exists; choose another name or give replace=True",
                                       out.string(), *save));
        std::vector<nmf::EpochReport> epochs;
        opt.on_epoch = [&epochs, &on_epoch](const nmf::EpochReport& e) {
          epochs.push_back(e);
          if (on_epoch.is_none()) return;
          py::gil_scoped_acquire gil;
          py::dict d;
          d["restart"] = e.restart;
          d["epoch"] = e.epoch;
          d["rel_error"] = e.rel_error;
          d["seconds"] = e.seconds;
          on_epoch(d);
        };
        const store::Selection sel{.image_globs = globs_from(images), .collection = collection};
        const auto t0 = std::chrono::steady_clock::now();
        const nmf::LearnedBasis learned = interruptible([&] { return nmf::learn_basis(stores, sel, opt); });
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const store::Basis& basis = learned.basis;
        if (save) {
          save_basis_released(out, *save, basis, replace, "nmf");
          std::error_code ec;
          std::filesystem::remove(opt.checkpoint, ec);
        }
        // the fields of `specula nmf --json`; basis and output are None when the basis is not saved
        const auto report = nmf::report_json(learned, {.store = stores.front().path().string(),
                                                       .basis = save,
                                                       .output = save ? std::optional(out.string()) : std::nullopt,
                                                       .seconds = seconds,
                                                       .epochs = epochs});
        return py::make_tuple(save ? with_origin(store::Basis(basis), out, *save) : py::cast(basis),
                              py::module_::import("json").attr("loads")(
                                  report.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace)));
      },
      py::arg("stores"), py::arg("k"), py::arg("images") = py::none(), py::arg("collection") = "",
      py::arg("init") = "nndsvd", py::arg("seed") = 0, py::arg("restarts") = 1, py::arg("max_epochs") = 100,
      py::arg("wave_blocks") = 8, py::arg("tol") = 1e-4, py::arg("negatives") = "clip", py::arg("name") = py::none(),
      py::arg("output") = py::none(), py::arg("checkpoint") = py::none(), py::arg("resume") = false,
      py::arg("replace") = false, py::arg("on_epoch") = py::none(),
      "Out-of-core NMF (reference §7.4) of every valid spectrum, as `specula nmf` does: returns (basis, report). With "
      "`name`, the basis is saved in `output` (default: the first store) and a checkpoint is kept beside it until "
      "then; on_epoch(dict) is called after every epoch.");
}

void def_project(py::module_& m) {
  m.def(
      "project",
      [](const BasisArg& basis_arg, const ArrayLike& spectra, const KArg& k, const OptArray& mask) -> ProjectResult {
        const store::Basis& basis = as<store::Basis>(basis_arg, "project", "basis", "Basis");
        if (py::isinstance<py::list>(k) || py::isinstance<py::tuple>(k)) {
          py::dict out;  // several k, as the CLI's -k 1,3,6,31
          for (const auto& one : k)
            out[one] = project_one(basis, spectra, py::reinterpret_borrow<py::object>(one), mask);
          return ProjectResult(std::move(out));
        }
        return ProjectResult(project_one(basis, spectra, k, mask));
      },
      py::arg("basis"), py::arg("spectra"), py::arg("k") = py::none(), py::arg("mask") = py::none(),
      "Projects spectra (any shape ending in bands; float32 in, float32 out) onto a basis as `specula project` does: "
      "the first k components of "
      "a PCA basis (eqs 7.2-7.3) or NNLS on every component of an NMF basis. Returns a dict: coefficients, "
      "reconstruction, error (per-spectrum L2), rms (per band, over spectra the mask keeps) and max_error; with a list "
      "of "
      "k (PCA), a dict of those dicts by k.");
}

}  // namespace

void init_analysis(py::module_& m) {
  init_basis(m);
  def_pca(m);
  def_nmf(m);
  def_project(m);
}

}  // namespace specula::python
