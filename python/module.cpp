// The `specula` Python module: exceptions, shared conversions, and the submodules' registration.
#include <fmt/format.h>

#include "specula/core/error.h"
#include "python/common.h"
#include "specula/version.h"

namespace specula::python {
namespace {

PyObject* error_type = nullptr;
PyObject* usage_type = nullptr;
PyObject* input_type = nullptr;
PyObject* library_type = nullptr;
PyObject* interrupted_type = nullptr;

// A new exception class specula.<name> deriving from `bases` (a class or a tuple), kept for the module's life.
PyObject* add_exception(py::module_& m, const char* name, PyObject* bases, const char* doc) {
  const std::string qualified = std::string("specula.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  if (!type) throw py::error_already_set();
  m.add_object(name, py::reinterpret_borrow<py::object>(type));
  return type;
}

}  // namespace

py::array_t<double> to_numpy(const Eigen::VectorXd& v) {
  py::array_t<double> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

py::array_t<double> to_numpy(const Eigen::MatrixXd& m) {
  py::array_t<double> out({py::ssize_t(m.rows()), py::ssize_t(m.cols())});
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(out.mutable_data(), m.rows(),
                                                                                        m.cols()) = m;
  return out;
}

Eigen::MatrixXd matrix_from(const py::handle& a, const std::string& what) {
  const auto arr = DoubleArray::ensure(a);
  if (!arr || arr.ndim() != 2)
    throw UsageError(fmt::format("{}: expected a 2-D array of numbers", what));
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      arr.data(), arr.shape(0), arr.shape(1));
}

Eigen::VectorXd vector_from(const py::handle& a, const std::string& what) {
  const auto arr = DoubleArray::ensure(a);
  if (!arr || arr.ndim() != 1) throw UsageError(fmt::format("{}: expected a 1-D array of numbers", what));
  return Eigen::Map<const Eigen::VectorXd>(arr.data(), arr.shape(0));
}

py::array_t<double> wavelengths_array(const WavelengthGrid& grid) {
  py::array_t<double> out(py::ssize_t(grid.size()));
  std::copy(grid.values().begin(), grid.values().end(), out.mutable_data());
  return out;
}

WavelengthGrid grid_from(const py::handle& w, const std::string& what) {
  if (py::isinstance<py::str>(w)) return WavelengthGrid::parse(w.cast<std::string>());
  const auto arr = DoubleArray::ensure(w);
  if (!arr || arr.ndim() != 1) throw UsageError(fmt::format("{}: expected a 1-D array of wavelengths in nm", what));
  return WavelengthGrid(std::vector<double>(arr.data(), arr.data() + arr.shape(0)), what);
}

std::vector<store::Store> stores_from(const py::handle& stores) {
  auto one = [](const py::handle& h) {
    if (py::isinstance<store::Store>(h)) return h.cast<store::Store>();
    return store::Store::open(py::module_::import("os").attr("fspath")(h).cast<std::string>());
  };
  std::vector<store::Store> out;
  if (py::isinstance<py::list>(stores) || py::isinstance<py::tuple>(stores)) {
    for (const auto& h : stores) out.push_back(one(h));
    if (out.empty()) throw UsageError("stores: give at least one store");
  } else {
    out.push_back(one(stores));
  }
  return out;
}

std::vector<std::string> globs_from(const py::handle& images) {
  if (images.is_none()) return {};
  if (py::isinstance<py::str>(images)) return {images.cast<std::string>()};
  return images.cast<std::vector<std::string>>();
}

std::string python_command_line(const std::string& function) {
  return fmt::format("python: specula.{} (specula {})", function, SPECULA_VERSION);
}

}  // namespace specula::python

PYBIND11_MODULE(specula, m) {
  namespace sp = specula::python;
  namespace py = pybind11;
  using namespace specula;
  m.doc() = "specula: spectral appearance data (stores, block streaming, PCA, NMF, codecs, BRDF grids, colour)";
  m.attr("__version__") = SPECULA_VERSION;
  sp::error_type = sp::add_exception(m, "Error", PyExc_Exception, "Base of every error specula raises.");
  sp::usage_type = sp::add_exception(m, "UsageError", sp::error_type, "A rule of the API was broken; the message states it.");
  {
    py::tuple bases = py::make_tuple(py::handle(sp::error_type), py::handle(PyExc_ValueError));
    sp::input_type = sp::add_exception(m, "InputError", bases.ptr(),
                                       "A file or value given to specula is malformed, inconsistent or unsupported.");
  }
  sp::library_type = sp::add_exception(m, "LibraryError", sp::error_type,
                                       "HDF5, zstd, the OS or another library reported a failure.");
  {
    py::tuple bases = py::make_tuple(py::handle(sp::error_type), py::handle(PyExc_KeyboardInterrupt));
    sp::interrupted_type = sp::add_exception(m, "Interrupted", bases.ptr(),
                                             "Ctrl-C stopped the work; the message says what was kept.");
  }
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(sp::input_type, e.what());
    } catch (const UsageError& e) {
      PyErr_SetString(sp::usage_type, e.what());
    } catch (const LibraryError& e) {
      PyErr_SetString(sp::library_type, e.what());
    } catch (const Interrupted& e) {
      PyErr_SetString(sp::interrupted_type, e.what());
    } catch (const Error& e) {
      PyErr_SetString(sp::error_type, e.what());
    }
  });
  sp::init_store(m);
  sp::init_analysis(m);
  sp::init_brdf(m);
  sp::init_bsdf(m);
}
