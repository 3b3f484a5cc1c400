#pragma once
// What the binding files share: numpy conversions without copies where the data can be handed over, wavelength
// grids, and how Python arguments name stores and selections.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Core>
#include <chrono>
#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::codec {
struct Environment;
}

namespace specula::python {

namespace py = pybind11;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

void init_store(py::module_& m);
void init_store_write(py::module_& m);
void init_blocks(py::module_& m);
void init_analysis(py::module_& m);
void init_brdf(py::module_& m);
void init_bsdf(py::module_& m);
void init_render(py::module_& m);
void init_fidelity(py::module_& m);
void init_filters(py::module_& m);
void init_resample(py::module_& m);

class PyStore;

/// A file that is not there: specula.MissingFileError, both an InputError and a FileNotFoundError.
class MissingFile : public InputError {
 public:
  using InputError::InputError;
};
/// An object a store does not hold: specula.MissingObjectError, both an InputError and a KeyError.
class MissingObject : public InputError {
 public:
  using InputError::InputError;
};

/// The path `p` (str or os.PathLike) names, made absolute, so messages show where it was looked for.
std::filesystem::path path_from(const py::handle& p);
/// As path_from, for a file that must exist; MissingFile "PATH: no such file" otherwise.
std::filesystem::path existing_file(const py::handle& p);

/// `h` as a T (a bound class): TypeError "fn: `name` must be a specula.TYPE, not TYPE_OF_H" instead of pybind's
/// listing of overloads and the argument's repr.
template <class T>
T& as(const py::handle& h, const char* fn, const char* name, const char* type) {
  if (!py::isinstance<T>(h))
    throw py::type_error(std::string(fn) + ": " + name + " must be a specula." + type + ", not " +
                         py::str(py::type::of(h).attr("__name__")).cast<std::string>());
  return h.cast<T&>();
}

/// specula.Store: a store opened for reading (mode "r") or also writing (mode "a"). Reads go to one committed state,
/// replaced by a newer one by refresh() and after every commit made through this module (so what this process
/// wrote is listed without reopening). In mode "a", writes outside a `with` block commit at once; inside one they
/// join the block's transaction, committed on a clean exit and abandoned (the store left as it was) on an exception.
class PyStore {
 public:
  PyStore(std::filesystem::path path, std::string mode);
  const std::filesystem::path& path() const { return path_; }
  const std::string& mode() const { return mode_; }
  /// The current committed state (refreshed first when this module committed since); MissingFile when a store
  /// opened with mode "a" has not been created yet.
  const store::Store& get() const;
  /// True when the store exists (a mode-"a" store is created by its first commit).
  bool exists() const;
  /// Reopens the latest committed state.
  void refresh() const;
  /// The open transaction (inside `with`) or a new one for a single write (`commit_now` set); UsageError in mode "r".
  store::StoreWriter& writer(bool replace, bool& commit_now);
  /// Commits a writer made for a single write.
  void commit_single();
  /// Abandons a writer made for a single write (its files are reclaimed later).
  void abandon_single() { single_.reset(); }
  /// Releases the open state (file handles) and abandons an open transaction; later calls reopen the store.
  void close() {
    tx_.reset();
    single_.reset();
    depth_ = 0;
    snapshot_.reset();
  }
  void enter();
  void exit(bool commit);
  bool in_transaction() const { return bool(tx_); }

 private:
  std::filesystem::path path_;
  std::string mode_;
  mutable std::optional<store::Store> snapshot_;
  mutable std::uint64_t seen_ = 0;
  std::unique_ptr<store::StoreWriter> tx_, single_;
  int depth_ = 0;
};

/// The lighting `env` names on `grid`: "default" (codec::default_environment) or a lat-long EXR path.
codec::Environment environment_from(const py::handle& env, const WavelengthGrid& grid);

/// The names of objects of `kind` (a plural group name: images, bases, ...) in s.
std::vector<std::string> names_of(const store::Store& s, const std::string& kind);
/// The store's current state; MissingObject (a KeyError) naming the store's full path and what it holds when it has
/// no `kind` (plural) called `name`.
const store::Store& holding(const PyStore& ps, const std::string& kind, const std::string& name);

/// Counts a commit made through this module (PyStore::get() then refreshes).
void note_commit();

// Arguments taken as Python objects and checked by the binding, named in signatures and docstrings by what they
// accept (pybind would say `object`).
inline bool any_object(PyObject*) { return true; }
#define SPECULA_PY_ARG(Name)                              \
  class Name : public py::object {                        \
   public:                                                \
    PYBIND11_OBJECT_DEFAULT(Name, py::object, any_object) \
  };
SPECULA_PY_ARG(ArrayLike)
SPECULA_PY_ARG(OptArray)
SPECULA_PY_ARG(WavelengthsArg)
SPECULA_PY_ARG(PathArg)
SPECULA_PY_ARG(OptPath)
SPECULA_PY_ARG(BasisArg)
SPECULA_PY_ARG(OptBasis)
SPECULA_PY_ARG(GridArg)
SPECULA_PY_ARG(BrdfArg)
SPECULA_PY_ARG(SpcData)
SPECULA_PY_ARG(DTypeArg)
SPECULA_PY_ARG(EnvArg)
SPECULA_PY_ARG(IlluminantArg)
SPECULA_PY_ARG(ImagesArg)
SPECULA_PY_ARG(KArg)
SPECULA_PY_ARG(OptFloat)
SPECULA_PY_ARG(OptStr)
SPECULA_PY_ARG(NamesArg)
SPECULA_PY_ARG(CallbackArg)
SPECULA_PY_ARG(StoresArg)
SPECULA_PY_ARG(StoreArg)
SPECULA_PY_ARG(BasisResult)
SPECULA_PY_ARG(ProjectResult)
SPECULA_PY_ARG(OptArrayResult)
SPECULA_PY_ARG(Float32Result)
SPECULA_PY_ARG(CountOrAuto)
SPECULA_PY_ARG(ReachArg)
SPECULA_PY_ARG(ResampleResult)
SPECULA_PY_ARG(TrainingArg)
SPECULA_PY_ARG(ExcludeArg)
#undef SPECULA_PY_ARG

/// A numpy array of `shape` that takes ownership of `owner` (a heap object holding the data at `data`).
template <class T, class Owner>
py::array_t<T> adopt(std::unique_ptr<Owner> owner, const T* data, std::vector<py::ssize_t> shape) {
  Owner* raw = owner.release();
  py::capsule base(raw, [](void* p) { delete static_cast<Owner*>(p); });
  return py::array_t<T>(std::move(shape), data, base);
}

/// A numpy array of `shape` taking over the vector's storage (no copy); also a Buffer's (core/buffer.h).
template <class T, class Allocator>
py::array_t<T> adopt(std::vector<T, Allocator>&& v, std::vector<py::ssize_t> shape) {
  auto owner = std::make_unique<std::vector<T, Allocator>>(std::move(v));
  const T* data = owner->data();
  return adopt<T>(std::move(owner), data, std::move(shape));
}

/// True when `a` is a numpy array of float32 (results are then given as float32).
inline bool is_float32(const py::handle& a) {
  return py::isinstance<py::array>(a) && py::reinterpret_borrow<py::array>(a).dtype().equal(py::dtype::of<float>());
}
/// `a` converted to float32 when `f32`, else `a`.
inline py::array as_dtype(py::array a, bool f32) {
  return f32 ? py::array(py::array_t<float, py::array::forcecast>::ensure(a)) : a;
}
/// `a` made read-only (returned for chaining).
py::array readonly(py::array a);
/// A read-only float64 view of a vector or (column-major) matrix held by `owner` (kept alive by the view); None
/// when empty.
py::object view(const Eigen::VectorXd& v, const py::handle& owner);
py::object view(const Eigen::MatrixXd& m, const py::handle& owner);
/// (kind, name) of the object `spec` names in the store (store::resolve_object), MissingObject (a KeyError) naming
/// the store's full path when it holds none.
std::pair<std::string, std::string> resolve(const PyStore& store, const std::string& spec);

/// A row-major copy of an Eigen vector or matrix as a 1-D or 2-D float64 array.
py::array_t<double> to_numpy(const Eigen::VectorXd& v);
py::array_t<double> to_numpy(const Eigen::MatrixXd& m);
/// A dense Eigen matrix from a 2-D array-like (copied); UsageError naming `what` otherwise.
Eigen::MatrixXd matrix_from(const py::handle& a, const std::string& what);
/// An Eigen vector from a 1-D array-like (copied); UsageError naming `what` otherwise.
Eigen::VectorXd vector_from(const py::handle& a, const std::string& what);

/// The wavelengths of a grid as a float64 array.
py::array_t<double> wavelengths_array(const WavelengthGrid& grid);
/// A grid from an array-like of nm values, or from a string "420:720:10" / "450,550,650".
WavelengthGrid grid_from(const py::handle& w, const std::string& what);

/// Stores named by a path, a specula.Store, or a list of them.
std::vector<store::Store> stores_from(const py::handle& stores);
/// Image globs from None, one string, or a sequence of strings.
std::vector<std::string> globs_from(const py::handle& images);
/// Runs f() on a worker thread while the calling thread, GIL released, waits for it and polls Python's signal
/// handlers. When one raises (Ctrl-C: KeyboardInterrupt), a stop is requested through core/interrupt.h, f's end
/// awaited, and the library's Interrupted (specula.Interrupted, a KeyboardInterrupt) or the handler's exception
/// raised. Call with the GIL held.
template <class F>
std::invoke_result_t<F&> interruptible(F&& f) {
  using R = std::invoke_result_t<F&>;
  std::packaged_task<R()> task(std::forward<F>(f));
  std::future<R> result = task.get_future();
  std::thread worker(std::move(task));
  bool signalled = false;
  for (;;) {
    bool ready;
    {
      py::gil_scoped_release release;
      ready = result.wait_for(std::chrono::milliseconds(50)) == std::future_status::ready;
    }
    if (ready) break;
    if (PyErr_CheckSignals() != 0) {
      signalled = true;
      request_interrupt();
      py::gil_scoped_release release;
      result.wait();
      break;
    }
  }
  {
    py::gil_scoped_release release;
    worker.join();
  }
  if (!signalled) return result.get();
  clear_interrupt();
  py::error_already_set signal_error;  // takes the handler's exception
  try {
    result.get();
  } catch (const Interrupted&) {
    throw;  // the library's message says what was kept
  } catch (...) {}
  throw signal_error;
}

/// The Provenance command line recorded on objects written from Python.
std::string python_command_line(const std::string& function);

}  // namespace specula::python

#define SPECULA_PY_ARG_NAME(Name, Text)                              \
  template <>                                                        \
  struct pybind11::detail::handle_type_name<specula::python::Name> { \
    static constexpr auto name = const_name(Text);                   \
  };
SPECULA_PY_ARG_NAME(ArrayLike, "numpy.typing.ArrayLike")
SPECULA_PY_ARG_NAME(OptArray, "numpy.typing.ArrayLike | None")
SPECULA_PY_ARG_NAME(WavelengthsArg, "str | numpy.typing.ArrayLike")
SPECULA_PY_ARG_NAME(PathArg, "str | os.PathLike[str]")
SPECULA_PY_ARG_NAME(OptPath, "str | os.PathLike[str] | None")
SPECULA_PY_ARG_NAME(BasisArg, "Basis")
SPECULA_PY_ARG_NAME(OptBasis, "Basis | None")
SPECULA_PY_ARG_NAME(GridArg, "Grid")
SPECULA_PY_ARG_NAME(BrdfArg, "Grid | SpcBrdf | numpy.typing.ArrayLike")
SPECULA_PY_ARG_NAME(SpcData, "bytes | str | os.PathLike[str]")
SPECULA_PY_ARG_NAME(DTypeArg, "numpy.typing.DTypeLike | None")
SPECULA_PY_ARG_NAME(EnvArg, "str | os.PathLike[str] | None")
SPECULA_PY_ARG_NAME(IlluminantArg, "str | numpy.typing.ArrayLike")
SPECULA_PY_ARG_NAME(ImagesArg, "str | Sequence[str] | None")
SPECULA_PY_ARG_NAME(KArg, "int | Sequence[int] | None")
SPECULA_PY_ARG_NAME(OptFloat, "float | None")
SPECULA_PY_ARG_NAME(OptStr, "str | None")
SPECULA_PY_ARG_NAME(NamesArg, "Sequence[str] | None")
SPECULA_PY_ARG_NAME(CallbackArg, "Callable[[dict], None] | None")
SPECULA_PY_ARG_NAME(StoresArg, "str | os.PathLike[str] | Store | Sequence[str | os.PathLike[str] | Store]")
SPECULA_PY_ARG_NAME(StoreArg, "str | os.PathLike[str] | Store")
SPECULA_PY_ARG_NAME(BasisResult, "Basis")
SPECULA_PY_ARG_NAME(ProjectResult, "dict[str, Any] | dict[int, dict[str, Any]]")
SPECULA_PY_ARG_NAME(OptArrayResult, "numpy.ndarray | None")
SPECULA_PY_ARG_NAME(Float32Result, "numpy.typing.NDArray[numpy.float32]")
SPECULA_PY_ARG_NAME(CountOrAuto, "int | str")
SPECULA_PY_ARG_NAME(ReachArg, "float | str | None")
SPECULA_PY_ARG_NAME(ResampleResult, "tuple[Grid, dict[str, Any]]")
SPECULA_PY_ARG_NAME(TrainingArg,
                    "str | os.PathLike[str] | Store | Sequence[str | os.PathLike[str] | Store | tuple[str, Grid]] | "
                    "Mapping[str, Grid]")
SPECULA_PY_ARG_NAME(ExcludeArg, "str | Sequence[str]")
#undef SPECULA_PY_ARG_NAME
