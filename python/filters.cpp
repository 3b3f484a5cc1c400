// specula.design_filters, read_filters and write_filters: broadband filters for a filter-wheel capture
// (acquire/filter_design.h, acquire/filters.h), the calls `specula filters design` makes, with the curves as numpy
// arrays and the expected-error report as the CLI's --json gives it.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "python/common.h"
#include "specula/acquire/filter_design.h"
#include "specula/acquire/filter_report.h"
#include "specula/acquire/filters.h"

namespace specula::python {
namespace {

// The curves as {"names", "wavelengths" (n,), "transmission" (K, n)} float64 arrays.
py::dict filters_dict(const acquire::FilterSet& f) {
  py::dict d;
  d["names"] = f.names;
  d["wavelengths"] = py::array_t<double>(py::ssize_t(f.nm.size()), f.nm.data());
  py::array_t<double> t({py::ssize_t(f.size()), py::ssize_t(f.nm.size())});
  auto w = t.mutable_unchecked<2>();
  for (std::size_t k = 0; k < f.size(); ++k)
    for (std::size_t i = 0; i < f.nm.size(); ++i) w(py::ssize_t(k), py::ssize_t(i)) = f.transmission[k][i];
  d["transmission"] = t;
  return d;
}

// A FilterSet from arrays: transmission (K, n) or (n,), wavelengths (n,), names (default F1 ... FK).
acquire::FilterSet filters_from(const ArrayLike& transmission, const ArrayLike& wavelengths, const NamesArg& names) {
  Eigen::MatrixXd t;
  const py::array a = py::array::ensure(transmission);
  if (a && a.ndim() == 1) {
    t = vector_from(transmission, "write_filters: transmission").transpose();
  } else {
    t = matrix_from(transmission, "write_filters: transmission");
  }
  const Eigen::VectorXd nm = vector_from(wavelengths, "write_filters: wavelengths");
  if (t.cols() != nm.size())
    throw UsageError(
        fmt::format("write_filters: transmission has {} values per filter, wavelengths {}", t.cols(), nm.size()));
  acquire::FilterSet f;
  f.nm.assign(nm.data(), nm.data() + nm.size());
  for (Eigen::Index k = 0; k < t.rows(); ++k) {
    const Eigen::VectorXd row = t.row(k).transpose();
    f.transmission.emplace_back(row.data(), row.data() + row.size());
  }
  if (names.is_none()) {
    for (Eigen::Index k = 0; k < t.rows(); ++k) f.names.push_back(fmt::format("F{}", k + 1));
  } else {
    f.names = names.cast<std::vector<std::string>>();
    if (f.names.size() != f.size())
      throw UsageError(fmt::format("write_filters: {} names for {} filters", f.names.size(), f.size()));
  }
  return f;
}

}  // namespace

void init_filters(py::module_& m) {
  m.def(
      "design_filters",
      [](const StoreArg& store_arg, const std::string& basis, int k, const std::string& method, double noise,
         double min_throughput, bool equal_exposure, const std::string& solve, double ridge, double peak,
         double light_kelvin, double colour_weight, const OptStr& train, const OptStr& test) {
        if (py::isinstance<py::list>(store_arg) || py::isinstance<py::tuple>(store_arg))
          throw UsageError("design_filters: give one store (a path or a specula.Store)");
        const std::vector<store::Store> stores = stores_from(store_arg);
        acquire::FilterDesignOptions o{.method = acquire::parse_filter_method(method),
                                       .solve = acquire::parse_filter_solve(solve),
                                       .k = k,
                                       .noise = noise,
                                       .per_filter_exposure = !equal_exposure,
                                       .min_throughput = min_throughput,
                                       .colour_weight = colour_weight,
                                       .ridge = ridge,
                                       .peak = peak,
                                       .light_kelvin = light_kelvin};
        acquire::check_filter_design(o);
        const std::string train_name = train.is_none() ? "" : train.cast<std::string>();
        const std::string test_name = test.is_none() ? "" : test.cast<std::string>();
        const acquire::FilterDesign d =
            interruptible([&] { return acquire::design_filters(stores.front(), basis, train_name, test_name, o); });
        // the fields of `specula filters design --json`, then the curves and the bands as arrays
        const nlohmann::ordered_json report = acquire::filter_design_json(d, o);
        py::dict r = py::module_::import("json").attr("loads")(report.dump());
        r.attr("update")(filters_dict(d.filters));
        r["bands"] = py::array_t<double>(py::ssize_t(d.bands.size()), d.bands.data());
        const std::vector<double> throughput = report["throughput"].get<std::vector<double>>();
        r["throughput"] = py::array_t<double>(py::ssize_t(throughput.size()), throughput.data());
        return r;
      },
      py::arg("store"), py::arg("basis"), py::arg("k") = 6, py::kw_only(), py::arg("method") = "optimal",
      py::arg("noise") = 0.002, py::arg("min_throughput") = 0.01, py::arg("equal_exposure") = false,
      py::arg("solve") = "wiener", py::arg("ridge") = 1e-3, py::arg("peak") = 0.9, py::arg("light_kelvin") = 3200.0,
      py::arg("colour_weight") = acquire::FilterDesignOptions{}.colour_weight, py::arg("train") = py::none(),
      py::arg("test") = py::none(),
      "Designs k broadband filters for basis `basis` of `store` as `specula filters design` does (docs/filters.md): "
      "method 'optimal' (super-Gaussians minimising the expected reconstruction error under camera noise) or 'nmf' "
      "(smoothed NMF components). Returns a dict: names, wavelengths (n,) and transmission (k, n) float64 (what "
      "write_filters takes), bands (the basis's wavelengths), throughput (each filter's white reading over an open "
      "filter's), roughness, and the expected spectral RMS on the training spectra and on held-out ones (`test`, or "
      "every fifth training spectrum): training and held_out, each a dict of spectra (their name), count, rms_mean, "
      "rms_median, rms_max and noise_rms.");
  m.def(
      "read_filters", [](const PathArg& path) { return filters_dict(acquire::read_filters_csv(existing_file(path))); },
      py::arg("path"),
      "Reads a filter CSV (docs/filters.md): a dict of names, wavelengths (n,) and transmission (k, n) float64. "
      "InputError naming the file and line for a malformed file.");
  m.def(
      "write_filters",
      [](const PathArg& path, const ArrayLike& transmission, const ArrayLike& wavelengths, const NamesArg& names) {
        acquire::write_filters_csv(path_from(path), filters_from(transmission, wavelengths, names));
      },
      py::arg("path"), py::arg("transmission"), py::arg("wavelengths"), py::arg("names") = py::none(),
      "Writes a filter CSV that simulate-capture --filters reads: transmission (k, n) or (n,) in [0, 1] on "
      "wavelengths (n,) nm, increasing; names default to F1 ... Fk. The file is replaced atomically; UsageError for "
      "values it could not read back (nothing written).");
}

}  // namespace specula::python
