// specula.Blocks and Store.blocks(): the block reader as a re-iterable sequence of numpy blocks read ahead on worker
// threads with the GIL released, into recycled buffers.
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>
#include <variant>

#include "python/common.h"
#include "specula/core/error.h"
#include "specula/store/block_reader.h"

namespace specula::python {
namespace {

// Buffers of max_block_spectra x bands values, recycled: a numpy block hands its buffer back when Python frees it,
// so a streaming pass touches the same few pages instead of faulting in fresh memory for every block.
template <class T>
class BufferPool {
 public:
  BufferPool(std::size_t capacity, std::size_t keep) : capacity_(capacity), keep_(keep) {}
  std::vector<T> take() {
    {
      std::lock_guard lock(mutex_);
      if (!free_.empty()) {
        std::vector<T> v = std::move(free_.back());
        free_.pop_back();
        return v;
      }
    }
    std::vector<T> v;
    v.reserve(capacity_);
    return v;
  }
  void give(std::vector<T>&& v) {
    std::lock_guard lock(mutex_);
    if (free_.size() < keep_) free_.push_back(std::move(v));
  }

 private:
  std::size_t capacity_, keep_;
  std::mutex mutex_;
  std::vector<std::vector<T>> free_;
};

// What a numpy block owns: its buffer, returned to the pool (if the iterator still lives) when the array dies.
template <class T>
struct Pooled {
  std::vector<T> values;
  std::weak_ptr<BufferPool<T>> pool;
  ~Pooled() {
    if (auto p = pool.lock()) p->give(std::move(values));
  }
};

// Block i of `reader` into a buffer from `pool`: float32 blocks are read straight into it and compacted in place.
template <class T>
std::vector<T> read_pooled(const store::BlockReader& reader, std::size_t i, store::BlockReader::RawBlock& raw,
                           BufferPool<T>& pool) {
  std::vector<T> out = pool.take();
  if constexpr (std::is_same_v<T, float>) {
    raw.values = std::move(out);
    reader.read_raw(i, raw);
    store::BlockReader::compact(raw, reader.bands(), raw.values.data());
    raw.values.resize(raw.valid * reader.bands());
    return std::move(raw.values);
  } else {
    reader.read_raw(i, raw);
    out.resize(raw.valid * reader.bands());
    store::BlockReader::compact(raw, reader.bands(), out.data());
    return out;
  }
}

// The iterator Store.blocks() returns. `depth` worker threads read the next blocks (each into its own raw buffer,
// then compacted into a pooled buffer) while Python works on the current one; blocks are yielded in order.
template <class T>
class BlockStream {
 public:
  using Value = T;
  BlockStream(std::shared_ptr<const store::BlockReader> reader, std::size_t depth)
      : reader_(std::move(reader)),
        depth_(std::max<std::size_t>(1, depth)),
        pool_(std::make_shared<BufferPool<T>>(reader_->max_block_spectra() * reader_->bands(), 2 * depth_ + 2)) {}
  BlockStream(const BlockStream&) = delete;
  BlockStream& operator=(const BlockStream&) = delete;
  ~BlockStream() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    work_.notify_all();
    for (auto& t : workers_) t.join();
  }

  /// Block `next` in order, waiting for it with the GIL released; false after the last.
  bool next(std::vector<T>& out) {
    const std::size_t n = reader_->block_count();
    if (yielded_ >= n) return false;
    if (workers_.empty())
      for (std::size_t w = 0; w < std::min(depth_, n); ++w) workers_.emplace_back([this] { work(); });
    std::unique_lock lock(mutex_);
    done_.wait(lock, [&] { return ready_.count(yielded_) != 0; });
    Result r = std::move(ready_.at(yielded_));
    ready_.erase(yielded_);
    ++yielded_;
    lock.unlock();
    work_.notify_all();
    if (r.error) std::rethrow_exception(r.error);
    out = std::move(r.values);
    return true;
  }

  /// Block i alone, on the calling thread.
  void read(std::size_t i, std::vector<T>& out) const {
    store::BlockReader::RawBlock raw;
    out = read_pooled(*reader_, i, raw, *pool_);
  }

  const std::shared_ptr<BufferPool<T>>& pool() const { return pool_; }

 private:
  struct Result {
    std::vector<T> values;
    std::exception_ptr error;
  };
  void work() {
    store::BlockReader::RawBlock raw;
    for (;;) {
      std::size_t i;
      {
        std::unique_lock lock(mutex_);
        work_.wait(lock, [&] { return stop_ || (issued_ < reader_->block_count() && issued_ < yielded_ + depth_); });
        if (stop_) return;
        i = issued_++;
      }
      Result r;
      try {
        r.values = read_pooled(*reader_, i, raw, *pool_);
      } catch (...) {
        r.error = std::current_exception();
      }
      {
        std::lock_guard lock(mutex_);
        ready_.emplace(i, std::move(r));
      }
      done_.notify_all();
    }
  }

  std::shared_ptr<const store::BlockReader> reader_;
  std::size_t depth_;
  std::shared_ptr<BufferPool<T>> pool_;
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable work_, done_;
  std::map<std::size_t, Result> ready_;
  std::size_t issued_ = 0, yielded_ = 0;
  bool stop_ = false;
};

template <class T>
py::array pooled_array(std::vector<T>&& values, std::size_t bands, const std::shared_ptr<BufferPool<T>>& pool) {
  const std::vector<py::ssize_t> shape{py::ssize_t(values.size() / bands), py::ssize_t(bands)};
  auto owner = std::make_unique<Pooled<T>>();
  owner->values = std::move(values);
  owner->pool = pool;
  const T* data = owner->values.data();
  return adopt<T>(std::move(owner), data, shape);
}

// Store.blocks(): a BlockStream of float32 or float64.
class Blocks {
 public:
  Blocks(std::shared_ptr<const store::BlockReader> reader, bool f64, std::size_t depth)
      : reader_(std::move(reader)), f64_(f64), depth_(depth) {
    start();
  }
  /// Starts a fresh pass (iter() on a Blocks that yielded blocks before), the old pass's workers joined.
  void rewind() {
    if (!started_) return;
    {
      py::gil_scoped_release release;
      stream_ = {};
    }
    start();
  }
  Blocks(const Blocks&) = delete;
  Blocks& operator=(const Blocks&) = delete;
  ~Blocks() {
    py::gil_scoped_release release;
    stream_ = {};  // joins the workers
  }

  py::array next() {
    started_ = true;
    return std::visit(
        [&](auto& s) -> py::array {
          using T = typename std::decay_t<decltype(*s)>::Value;
          std::vector<T> values;
          bool more;
          {
            py::gil_scoped_release release;
            more = s->next(values);
          }
          if (!more) throw py::stop_iteration();
          return pooled_array(std::move(values), reader_->bands(), s->pool());
        },
        stream_);
  }

  py::array read(std::size_t i) const {
    if (i >= reader_->block_count())
      throw UsageError(
          fmt::format("read: block {} of {}; give 0 to {}", i, reader_->block_count(), reader_->block_count() - 1));
    return std::visit(
        [&](auto& s) -> py::array {
          using T = typename std::decay_t<decltype(*s)>::Value;
          std::vector<T> values;
          {
            py::gil_scoped_release release;
            s->read(i, values);
          }
          return pooled_array(std::move(values), reader_->bands(), s->pool());
        },
        stream_);
  }

  const store::BlockReader& reader() const { return *reader_; }
  bool f64() const { return f64_; }

 private:
  void start() {
    if (f64_)
      stream_ = std::make_unique<BlockStream<double>>(reader_, depth_);
    else
      stream_ = std::make_unique<BlockStream<float>>(reader_, depth_);
    started_ = false;
  }
  std::shared_ptr<const store::BlockReader> reader_;
  bool f64_;
  std::size_t depth_;
  bool started_ = false;
  std::variant<std::unique_ptr<BlockStream<float>>, std::unique_ptr<BlockStream<double>>> stream_;
};

bool is_float64(const py::handle& dtype) {
  if (dtype.is_none()) return false;
  const py::dtype dt = py::dtype::from_args(py::reinterpret_borrow<py::object>(dtype));
  if (dt.is(py::dtype::of<double>()) || dt.equal(py::dtype::of<double>())) return true;
  if (dt.equal(py::dtype::of<float>())) return false;
  throw UsageError(
      fmt::format("dtype {}: blocks are numpy.float32 or numpy.float64", dt.attr("name").cast<std::string>()));
}

}  // namespace

void init_blocks(py::module_& m) {
  py::class_<Blocks>(
      m, "Blocks",
      "The valid spectra of a selection in blocks (n x bands arrays, each owned by the caller) that follow "
      "the storage chunks; the next blocks are read on worker threads while Python works on this one. "
      "Every iteration (a for loop, list()) is a fresh pass from the first block.")
      .def("__iter__",
           [](py::object self) {
             self.cast<Blocks&>().rewind();
             return self;
           })
      .def("__next__", &Blocks::next)
      .def("__len__", [](const Blocks& b) { return b.reader().block_count(); })
      .def("__repr__",
           [](const Blocks& b) {
             const auto& r = b.reader();
             std::string sources;
             for (std::size_t i = 0; i < r.source_names().size() && i < 4; ++i)
               sources += (i ? ", " : "") + r.source_names()[i];
             if (r.source_names().size() > 4) sources += fmt::format(", ... ({} sources)", r.source_names().size());
             return fmt::format("<specula.Blocks {} blocks, {} spectra x {} bands ({}), {}, from {}>", r.block_count(),
                                r.spectra(), r.bands(), r.wavelengths().describe(), b.f64() ? "float64" : "float32",
                                sources);
           })
      .def("read", &Blocks::read, py::arg("index"), "Block `index` alone (random access).")
      .def_property_readonly(
          "spectra", [](const Blocks& b) { return b.reader().spectra(); }, "Valid spectra in all blocks.")
      .def_property_readonly("bands", [](const Blocks& b) { return b.reader().bands(); })
      .def_property_readonly("block_count", [](const Blocks& b) { return b.reader().block_count(); })
      .def_property_readonly("max_block_spectra", [](const Blocks& b) { return b.reader().max_block_spectra(); })
      .def_property_readonly("wavelengths", [](const Blocks& b) { return wavelengths_array(b.reader().wavelengths()); })
      .def_property_readonly("units", [](const Blocks& b) { return b.reader().units(); })
      .def_property_readonly("sources", [](const Blocks& b) { return b.reader().source_names(); })
      .def_property_readonly("dtype",
                             [](const Blocks& b) { return b.f64() ? py::dtype::of<double>() : py::dtype::of<float>(); })
      .def(
          "block_source",
          [](const Blocks& b, std::size_t i) { return b.reader().source_names().at(b.reader().block_source(i)); },
          py::arg("index"), "The source (image or collection) block `index` comes from.")
      .def(
          "block_first_row", [](const Blocks& b, std::size_t i) { return b.reader().block_first_row(i); },
          py::arg("index"), "The first row (image row or spectrum) of block `index` in its source.")
      .def(
          "describe_block", [](const Blocks& b, std::size_t i) { return b.reader().describe_block(i); },
          py::arg("index"), "Where block `index` lies, as messages name it.");

  py::class_<PyStore>(py::reinterpret_borrow<py::object>(m.attr("Store")))
      .def(
          "blocks",
          [](const PyStore& ps, const ImagesArg& images, const std::string& collection, const std::string& samples,
             const DTypeArg& dtype, std::size_t min_block_pixels, std::optional<std::size_t> prefetch) {
            const bool f64 = is_float64(dtype);
            const store::Store& s = ps.get();
            if (!collection.empty()) holding(ps, "collections", collection);
            if (!samples.empty()) holding(ps, "samples", samples);
            const store::Selection sel{.image_globs = globs_from(images), .collection = collection, .samples = samples};
            std::shared_ptr<const store::BlockReader> reader;
            {
              py::gil_scoped_release release;
              reader = std::make_shared<const store::BlockReader>(s, sel, min_block_pixels);
            }
            return std::make_unique<Blocks>(reader, f64,
                                            prefetch ? *prefetch : std::size_t(std::max(1, omp_get_max_threads() - 1)));
          },
          py::arg("images") = py::none(), py::arg("collection") = "", py::arg("samples") = "",
          py::arg("dtype") = py::none(), py::arg("min_block_pixels") = 32768, py::arg("prefetch") = py::none(),
          "Every valid spectrum of the selected images (globs; all when None), or of one collection or samples set, "
          "as a re-iterable specula.Blocks of (n, bands) arrays of `dtype` (numpy.float32, the default, or "
          "numpy.float64).");
  ;
}

}  // namespace specula::python
