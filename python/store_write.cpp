// Writing from Python: Store.write_image, write_collection, write_basis, write_grid, write_prior and remove, each
// through a StoreWriter transaction (the `with` block's, or one of its own committed at once), provenance naming
// Python.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>

#include "python/common.h"
#include "specula/acquire/prior.h"
#include "specula/store/basis.h"

namespace specula::python {
namespace {

using U8Array = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

store::Provenance python_provenance(const std::string& function, const std::string& source) {
  return {
      .source_file = source, .importer = "python", .command_line = python_command_line(function), .created_utc = {}};
}

// Runs add(writer) in the open transaction or in one of its own, committed when add returns; a failure abandons a
// transaction of its own (the store is left as it was).
template <class F>
void write(PyStore& ps, bool replace, F&& add) {
  bool now = false;
  store::StoreWriter& w = ps.writer(replace, now);
  try {
    add(w);
    if (now) {
      py::gil_scoped_release release;
      ps.commit_single();
    }
  } catch (const InputError& e) {
    if (now) ps.abandon_single();
    const std::string msg = e.what();
    const std::string library_fix = "allow replacing it";
    if (msg.find("exists already") == std::string::npos || !msg.ends_with(library_fix)) throw;
    throw InputError(ps.path().string() + msg.substr(msg.find(':'), msg.size() - msg.find(':') - library_fix.size()) +
                     "give replace=True");
  } catch (...) {
    if (now) ps.abandon_single();
    throw;
  }
}

void write_image(PyStore& ps, const std::string& name, const ArrayLike& cube_arg, const WavelengthsArg& wavelengths,
                 const OptArray& mask_arg, const std::string& units, const OptArray& fwhm_arg, bool replace,
                 const std::string& source) {
  store::validate_name(name, "image");
  const auto cube = FloatArray::ensure(cube_arg);
  if (!cube || cube.ndim() != 3)
    throw UsageError(fmt::format("write_image: {}: cube must be a (height, width, bands) array of numbers", name));
  const std::size_t h = std::size_t(cube.shape(0)), w = std::size_t(cube.shape(1)), b = std::size_t(cube.shape(2));
  const WavelengthGrid grid = grid_from(wavelengths, "write_image wavelengths");
  if (grid.size() != b)
    throw UsageError(fmt::format("write_image: {}: {} wavelengths for a cube of {} bands", name, grid.size(), b));
  U8Array mask;  // read only when mask_arg is given (a default array_t is an empty array, not a null one)
  if (!mask_arg.is_none()) {
    mask = U8Array::ensure(mask_arg);
    if (!mask || mask.ndim() != 2 || std::size_t(mask.shape(0)) != h || std::size_t(mask.shape(1)) != w)
      throw UsageError(fmt::format("write_image: {}: mask must be ({}, {}) (nonzero = valid)", name, h, w));
  }
  std::vector<double> fwhm;
  if (!fwhm_arg.is_none()) {
    const Eigen::VectorXd f = vector_from(fwhm_arg, "write_image fwhm");
    if (std::size_t(f.size()) != b) throw UsageError(fmt::format("write_image: {}: fwhm needs {} values", name, b));
    fwhm.assign(f.data(), f.data() + f.size());
  }
  write(ps, replace, [&](store::StoreWriter& writer) {
    py::gil_scoped_release release;
    const std::size_t chunk =
        writer.create_image(name, h, w, grid, fwhm, units, python_provenance("Store.write_image", source));
    // Strips of whole chunks, about 64 MiB: the chunks of a strip are compressed in parallel.
    const std::size_t strip =
        chunk * std::max<std::size_t>(1, (std::size_t{64} << 20) / (chunk * w * b * sizeof(float)));
    const float* data = cube.data();
    const std::uint8_t* m = mask_arg.is_none() ? nullptr : mask.data();
    for (std::size_t y = 0; y < h; y += strip) {
      const std::size_t rows = std::min(strip, h - y);
      writer.write_image_rows(name, y, rows, std::span(data + y * w * b, rows * w * b),
                              m ? std::span(m + y * w, rows * w) : std::span<const std::uint8_t>());
    }
  });
}

void write_collection(PyStore& ps, const std::string& name, const ArrayLike& spectra_arg,
                      const WavelengthsArg& wavelengths, const NamesArg& names_arg, const std::string& units,
                      bool replace, const std::string& source) {
  store::validate_name(name, "collection");
  const auto spectra = FloatArray::ensure(spectra_arg);
  if (!spectra || spectra.ndim() != 2)
    throw UsageError(fmt::format("write_collection: {}: spectra must be a (size, bands) array of numbers", name));
  store::Collection c;
  c.wavelengths = grid_from(wavelengths, "write_collection wavelengths");
  const std::size_t n = std::size_t(spectra.shape(0));
  if (c.bands() != std::size_t(spectra.shape(1)))
    throw UsageError(
        fmt::format("write_collection: {}: {} wavelengths for spectra of {} bands", name, c.bands(), spectra.shape(1)));
  if (names_arg.is_none()) {
    for (std::size_t i = 0; i < n; ++i) c.names.push_back(std::to_string(i));
  } else {
    c.names = names_arg.cast<std::vector<std::string>>();
    if (c.names.size() != n)
      throw UsageError(fmt::format("write_collection: {}: {} names for {} spectra", name, c.names.size(), n));
  }
  c.values.assign(spectra.data(), spectra.data() + spectra.size());
  c.units = units;
  c.provenance = python_provenance("Store.write_collection", source);
  write(ps, replace, [&](store::StoreWriter& writer) {
    py::gil_scoped_release release;
    writer.add_collection(name, c);
  });
}

std::string type_name(const py::handle& h) { return py::str(py::type::of(h).attr("__name__")).cast<std::string>(); }

// A grid in memory, named `name`, kept alive by `keep` while the prior is built from it (not copied).
acquire::TrainingGrid memory_grid(const py::handle& name, const py::handle& grid, const std::string& what,
                                  std::vector<py::object>& keep) {
  if (!py::isinstance<py::str>(name))
    throw py::type_error("write_prior: the name in " + what + " must be a str, not " + type_name(name));
  store::validate_name(name.cast<std::string>(), "grid");
  keep.push_back(py::reinterpret_borrow<py::object>(grid));
  const store::Grid& g = as<store::Grid>(grid, "write_prior", what.c_str(), "Grid");
  return acquire::memory_training_grid(std::shared_ptr<const store::Grid>(&g, [](const store::Grid*) {}),
                                       name.cast<std::string>());
}

// One item of write_prior's grids: a str as the CLI's GRID argument, a path or specula.Store for all the store's
// grids, or a (name, specula.Grid) pair.
acquire::TrainingSource training_source(const py::handle& item, const std::string& what,
                                        std::vector<py::object>& keep) {
  if (py::isinstance<py::str>(item)) return item.cast<std::string>();
  if (py::isinstance<PyStore>(item)) return item.cast<PyStore&>().get();
  if (py::hasattr(item, "__fspath__")) return store::Store::open(existing_file(item));
  if (py::isinstance<py::tuple>(item) && py::len(item) == 2) {
    const auto pair = py::reinterpret_borrow<py::tuple>(item);
    return memory_grid(pair[0], pair[1], what, keep);
  }
  throw py::type_error("write_prior: " + what +
                       " must be a 'STORE.h5:NAME' str, a store (path or specula.Store) or a (name, specula.Grid) "
                       "pair, not " +
                       type_name(item));
}

// write_prior's grids: one item, a sequence of them, or a dict of names to specula.Grids.
std::vector<acquire::TrainingSource> training_sources(const TrainingArg& grids, std::vector<py::object>& keep) {
  std::vector<acquire::TrainingSource> sources;
  if (py::isinstance<py::str>(grids) || py::isinstance<PyStore>(grids) || py::hasattr(grids, "__fspath__")) {
    sources.push_back(training_source(grids, "grids", keep));
  } else if (py::isinstance<py::dict>(grids)) {
    for (const auto& [name, grid] : py::reinterpret_borrow<py::dict>(grids))
      sources.emplace_back(memory_grid(name, grid, "grids[" + py::repr(name).cast<std::string>() + "]", keep));
  } else if (py::isinstance<py::sequence>(grids)) {
    const auto seq = py::reinterpret_borrow<py::sequence>(grids);
    for (std::size_t i = 0; i < seq.size(); ++i)
      sources.push_back(training_source(seq[i], fmt::format("grids[{}]", i), keep));
  } else {
    throw py::type_error("write_prior: grids must be a sequence of grids or stores, or a dict of specula.Grids, not " +
                         type_name(grids));
  }
  return sources;
}

// write_prior's exclude: one name or a sequence of them.
std::vector<std::string> exclude_names(const ExcludeArg& exclude) {
  if (py::isinstance<py::str>(exclude)) return {exclude.cast<std::string>()};
  if (!py::isinstance<py::sequence>(exclude))
    throw py::type_error("write_prior: exclude must be a str or a sequence of str, not " + type_name(exclude));
  std::vector<std::string> names;
  const auto seq = py::reinterpret_borrow<py::sequence>(exclude);
  for (std::size_t i = 0; i < seq.size(); ++i) {
    if (!py::isinstance<py::str>(seq[i]))
      throw py::type_error(fmt::format("write_prior: exclude[{}] must be a str, not {}", i, type_name(seq[i])));
    names.push_back(seq[i].cast<std::string>());
  }
  return names;
}

// The prior's tables as write_prior returns them (what `specula prior build` prints, and more).
py::dict prior_report(const PyStore& ps, const std::string& name, const acquire::BrdfPrior& p, double seconds) {
  auto array = [](const std::vector<double>& v) { return py::array_t<double>(py::ssize_t(v.size()), v.data()); };
  py::dict d;
  d["name"] = name;
  d["store"] = ps.path().string();
  d["k"] = p.k();
  d["cells"] = p.cells();
  d["channels"] = p.channels();
  d["wavelengths"] = wavelengths_array(p.wavelengths);
  d["knots"] = array(p.knots);
  d["epsilon"] = p.epsilon;
  d["variances"] = array(p.variances);
  d["training"] = p.training;
  d["retro_exponents"] = array(p.retro_exponents);
  d["retro_rise"] = array(p.retro_rise);
  d["seconds"] = seconds;
  return d;
}

py::dict write_prior(PyStore& ps, const std::string& name, const TrainingArg& grids_arg, const ExcludeArg& exclude_arg,
                     long long channels, long long components, double epsilon, bool replace) {
  const auto t0 = std::chrono::steady_clock::now();
  store::validate_name(name, "prior");
  if (channels < 0) throw UsageError(fmt::format("write_prior: channels = {}: give 2 to 64", channels));
  if (components < 0) throw UsageError(fmt::format("write_prior: components = {}: give a count (0: all)", components));
  std::vector<py::object> keep;  // the Grids in memory, alive while the prior is built from them
  const std::vector<acquire::TrainingSource> sources = training_sources(grids_arg, keep);
  const std::vector<std::string> exclude = exclude_names(exclude_arg);
  std::vector<acquire::TrainingGrid> grids;
  {
    py::gil_scoped_release release;
    grids = acquire::training_grids(
        sources, exclude,
        [](const std::string& spec) -> acquire::TrainingGrid {
          throw UsageError("write_prior: '" + spec +
                           "' is neither 'STORE.h5:NAME' nor a store; read the file (specula.read_spgrid, "
                           "spc_decode, read_bsdf) and give (name, Grid)");
        },
        "write_prior", "exclude");
  }
  const acquire::PriorOptions po{
      .channels = std::size_t(channels), .components = std::size_t(components), .epsilon = epsilon};
  const std::string command_line = python_command_line("Store.write_prior");
  acquire::BrdfPrior prior;
  write(ps, replace, [&](store::StoreWriter& w) {
    prior = interruptible([&] { return acquire::build_prior(grids, po, w, name, command_line); });
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return prior_report(ps, name, prior, seconds);
}

}  // namespace

void init_store_write(py::module_& m) {
  auto cls = py::reinterpret_borrow<py::object>(m.attr("Store"));
  py::class_<PyStore> store(cls);
  store
      .def("write_image", &write_image, py::arg("name"), py::arg("cube"), py::arg("wavelengths"),
           py::arg("mask") = py::none(), py::arg("units") = "unknown", py::arg("fwhm") = py::none(),
           py::arg("replace") = false, py::arg("source") = "",
           "Writes image `name` from a (height, width, bands) array (float32 used in place, others converted) on "
           "`wavelengths` (nm values or '400:700:10'); mask (height, width), nonzero = valid (None: every pixel); "
           "units as the CLI's (reflectance, radiance, counts or free text); replace=True replaces an image of that "
           "name. Chunked and compressed as `specula import` writes. Committed at once outside `with`.")
      .def("write_collection", &write_collection, py::arg("name"), py::arg("spectra"), py::arg("wavelengths"),
           py::arg("names") = py::none(), py::arg("units") = "unknown", py::arg("replace") = false,
           py::arg("source") = "",
           "Writes collection `name`: (size, bands) spectra, their names (default '0', '1', ...).")
      .def(
          "write_basis",
          [](PyStore& ps, const std::string& name, const BasisArg& basis, bool replace) {
            store::validate_name(name, "basis");
            store::Basis b = as<store::Basis>(basis, "write_basis", "basis", "Basis");
            if (b.provenance.importer.empty()) b.provenance = python_provenance("Store.write_basis", "");
            write(ps, replace, [&](store::StoreWriter& w) {
              py::gil_scoped_release release;
              w.add_basis(name, b);
            });
          },
          py::arg("name"), py::arg("basis"), py::arg("replace") = false, "Writes a specula.Basis as basis `name`.")
      .def(
          "write_grid",
          [](PyStore& ps, const std::string& name, const GridArg& grid, bool replace) {
            store::validate_name(name, "grid");
            store::Grid g = as<store::Grid>(grid, "write_grid", "grid", "Grid");
            if (g.provenance.importer.empty()) g.provenance = python_provenance("Store.write_grid", "");
            write(ps, replace, [&](store::StoreWriter& w) {
              py::gil_scoped_release release;
              w.add_grid(name, g);
            });
          },
          py::arg("name"), py::arg("grid"), py::arg("replace") = false, "Writes a specula.Grid as grid `name`.")
      .def("write_prior", &write_prior, py::arg("name"), py::arg("grids"), py::kw_only(),
           py::arg("exclude") = py::tuple(), py::arg("channels") = 8, py::arg("components") = 0,
           py::arg("epsilon") = 1e-3, py::arg("replace") = false,
           "Learns a BRDF prior from `grids` and writes it as prior `name`, as `specula prior build` does "
           "(docs/prior.md): each item a 'STORE.h5:NAME' str (streamed by rows), a store (a path or specula.Store: "
           "all its grids) or a (name, specula.Grid) pair (a dict of them too); `exclude` the grid names left out; "
           "`channels` knots of the spectral basis, `components` kept (0: all), `epsilon` of the log-relative "
           "mapping (1/sr). Returns the prior's k, cells, channels, wavelengths, knots, epsilon, variances, "
           "training names, retro_exponents, retro_rise and seconds. Committed at once outside `with`.")
      .def(
          "remove",
          [](PyStore& ps, const std::string& spec) {
            const auto [kind, name] = resolve(ps, spec);
            write(ps, false, [&](store::StoreWriter& w) { w.remove(kind, name); });
          },
          py::arg("name"), "Removes an object (a name, or kind/name when several kinds use it).");
}

}  // namespace specula::python
