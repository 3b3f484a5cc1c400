#pragma once
// What the binding files share: numpy conversions without copies where the data can be handed over, wavelength
// grids, and how Python arguments name stores and selections.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Core>
#include <chrono>
#include <future>
#include <memory>
#include <thread>
#include <type_traits>
#include <string>
#include <vector>

#include "specula/core/interrupt.h"
#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::python {

namespace py = pybind11;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

void init_store(py::module_& m);
void init_analysis(py::module_& m);
void init_brdf(py::module_& m);
void init_bsdf(py::module_& m);

/// A numpy array of `shape` that takes ownership of `owner` (a heap object holding the data at `data`).
template <class T, class Owner>
py::array_t<T> adopt(std::unique_ptr<Owner> owner, const T* data, std::vector<py::ssize_t> shape) {
  Owner* raw = owner.release();
  py::capsule base(raw, [](void* p) { delete static_cast<Owner*>(p); });
  return py::array_t<T>(std::move(shape), data, base);
}

/// A numpy array of `shape` taking over the vector's storage (no copy).
template <class T>
py::array_t<T> adopt(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  auto owner = std::make_unique<std::vector<T>>(std::move(v));
  const T* data = owner->data();
  return adopt<T>(std::move(owner), data, std::move(shape));
}

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

/// Stores named by a path, a Store, or a list of them.
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
  } catch (...) {
  }
  throw signal_error;
}

/// The Provenance command line recorded on objects written from Python.
std::string python_command_line(const std::string& function);

}  // namespace specula::python
