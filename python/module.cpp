// The `specula` Python module: exceptions, shared conversions, and the submodules' registration.
#include <fmt/format.h>

#include <atomic>

#include "python/common.h"
#include "specula/core/error.h"
#include "specula/version.h"

namespace specula::python {
namespace {

PyObject* error_type = nullptr;
PyObject* usage_type = nullptr;
PyObject* input_type = nullptr;
PyObject* library_type = nullptr;
PyObject* interrupted_type = nullptr;
PyObject* missing_file_type = nullptr;
PyObject* missing_object_type = nullptr;
std::atomic<std::uint64_t> commit_count{0};

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

py::array readonly(py::array a) {
  a.attr("flags").attr("writeable") = false;
  return a;
}

py::object view(const Eigen::VectorXd& v, const py::handle& owner) {
  if (v.size() == 0) return py::none();
  return readonly(py::array_t<double>({py::ssize_t(v.size())}, v.data(), owner));
}

py::object view(const Eigen::MatrixXd& m, const py::handle& owner) {
  if (m.size() == 0) return py::none();
  const py::ssize_t d = sizeof(double);
  return readonly(py::array_t<double>({py::ssize_t(m.rows()), py::ssize_t(m.cols())}, {d, d * py::ssize_t(m.rows())},
                                      m.data(), owner));
}

std::pair<std::string, std::string> resolve(const PyStore& ps, const std::string& spec) {
  const store::Store& s = ps.get();
  try {
    return store::resolve_object(s, spec);
  } catch (const InputError& e) {
    const std::string msg = e.what();
    if (msg.rfind(s.label() + ": no ", 0) == 0) throw MissingObject(ps.path().string() + msg.substr(s.label().size()));
    throw;
  }
}

Eigen::MatrixXd matrix_from(const py::handle& a, const std::string& what) {
  const auto arr = DoubleArray::ensure(a);
  if (!arr || arr.ndim() != 2) throw UsageError(fmt::format("{}: expected a 2-D array of numbers", what));
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

std::filesystem::path path_from(const py::handle& p) {
  if (!py::isinstance<py::str>(p) && !py::hasattr(p, "__fspath__"))
    throw py::type_error("expected a path (str or os.PathLike), not " +
                         py::str(py::type::of(p).attr("__name__")).cast<std::string>());
  return std::filesystem::absolute(py::module_::import("os").attr("fspath")(p).cast<std::string>()).lexically_normal();
}

std::filesystem::path existing_file(const py::handle& p) {
  std::filesystem::path path = path_from(p);
  if (!std::filesystem::exists(path)) throw MissingFile(path.string() + ": no such file");
  return path;
}

void note_commit() { ++commit_count; }

PyStore::PyStore(std::filesystem::path path, std::string mode) : path_(std::move(path)), mode_(std::move(mode)) {
  if (mode_ != "r" && mode_ != "a")
    throw UsageError(
        fmt::format("Store: mode '{}': give 'r' (read) or 'a' (read and write; created if absent)", mode_));
  if (mode_ == "r" && !std::filesystem::exists(path_))
    throw MissingFile(path_.string() + ": no such file (give mode=\"a\" to create a store)");
  if (exists()) refresh();
}

bool PyStore::exists() const { return snapshot_.has_value() || std::filesystem::exists(path_); }

void PyStore::refresh() const {
  seen_ = commit_count;
  if (!std::filesystem::exists(path_)) {
    if (mode_ == "r" || snapshot_) throw MissingFile(path_.string() + ": no such file (removed since it was opened?)");
    return;
  }
  snapshot_ = store::Store::open(path_);
}

const store::Store& PyStore::get() const {
  if (seen_ != commit_count || !snapshot_) refresh();
  if (!snapshot_)
    throw MissingFile(path_.string() +
                      ": no such file yet (a store opened with mode \"a\" is created by its first write)");
  return *snapshot_;
}

store::StoreWriter& PyStore::writer(bool replace, bool& commit_now) {
  if (mode_ != "a")
    throw UsageError(path_.string() + ": opened read-only; open it with specula.Store(path, mode=\"a\") to write");
  commit_now = !tx_;
  store::StoreWriter* w = tx_.get();
  if (!w) {
    single_ = std::make_unique<store::StoreWriter>(
        path_,
        store::WriteOptions{.compression = {}, .replace = replace, .command_line = python_command_line("Store")});
    w = single_.get();
  }
  w->set_replace(replace);
  return *w;
}

void PyStore::commit_single() {
  std::unique_ptr<store::StoreWriter> w = std::move(single_);
  if (!w) return;
  w->commit();
  note_commit();
}

void PyStore::enter() {
  if (mode_ == "a" && depth_++ == 0)
    tx_ = std::make_unique<store::StoreWriter>(
        path_, store::WriteOptions{.compression = {}, .replace = false, .command_line = python_command_line("Store")});
}

void PyStore::exit(bool commit) {
  if (mode_ != "a" || (depth_ > 0 && --depth_ > 0)) return;  // depth 0: close() ended the block's transaction
  std::unique_ptr<store::StoreWriter> w = std::move(tx_);
  if (commit && w) {
    w->commit();
    note_commit();
  }
}

std::vector<store::Store> stores_from(const py::handle& stores) {
  auto one = [](const py::handle& h) {
    if (py::isinstance<PyStore>(h)) return h.cast<PyStore&>().get();
    return store::Store::open(existing_file(h));
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

PYBIND11_MODULE(_specula, m) {
  namespace sp = specula::python;
  namespace py = pybind11;
  using namespace specula;
  m.doc() = "specula: spectral appearance data (stores, block streaming, PCA, NMF, codecs, BRDF grids, colour)";
  m.attr("__version__") = SPECULA_VERSION;
  sp::error_type = sp::add_exception(m, "Error", PyExc_Exception, "Base of every error specula raises.");
  {
    py::tuple bases = py::make_tuple(py::handle(sp::error_type), py::handle(PyExc_ValueError));
    sp::usage_type =
        sp::add_exception(m, "UsageError", bases.ptr(), "A rule of the API was broken; the message states it.");
  }
  {
    py::tuple bases = py::make_tuple(py::handle(sp::error_type), py::handle(PyExc_ValueError));
    sp::input_type = sp::add_exception(m, "InputError", bases.ptr(),
                                       "A file or value given to specula is malformed, inconsistent or unsupported.");
  }
  {
    py::tuple bases = py::make_tuple(py::handle(sp::input_type), py::handle(PyExc_FileNotFoundError));
    sp::missing_file_type =
        sp::add_exception(m, "MissingFileError", bases.ptr(),
                          "A file specula was asked to read is not there (the message gives its full path).");
  }
  {
    py::tuple bases = py::make_tuple(py::handle(sp::input_type), py::handle(PyExc_KeyError));
    sp::missing_object_type =
        sp::add_exception(m, "MissingObjectError", bases.ptr(), "A store holds no object of the name asked for.");
  }
  sp::library_type =
      sp::add_exception(m, "LibraryError", sp::error_type, "HDF5, zstd, the OS or another library reported a failure.");
  {
    py::tuple bases = py::make_tuple(py::handle(sp::error_type), py::handle(PyExc_KeyboardInterrupt));
    sp::interrupted_type =
        sp::add_exception(m, "Interrupted", bases.ptr(), "Ctrl-C stopped the work; the message says what was kept.");
  }
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const sp::MissingFile& e) {
      PyErr_SetString(sp::missing_file_type, e.what());
    } catch (const sp::MissingObject& e) {
      PyErr_SetString(sp::missing_object_type, e.what());
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
  sp::init_store_write(m);
  sp::init_blocks(m);
  sp::init_analysis(m);
  sp::init_brdf(m);
  sp::init_bsdf(m);
  sp::init_render(m);
  sp::init_fidelity(m);
  sp::init_filters(m);
  sp::init_resample(m);
}
