// specula.Store: a store's objects as numpy arrays and info dicts, and Store.blocks(), the block reader as an
// iterator of numpy blocks read ahead on worker threads with the GIL released.
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>
#include <variant>

#include "specula/core/error.h"
#include "python/common.h"
#include "specula/store/block_reader.h"

namespace specula::python {
namespace {

py::dict provenance_dict(const store::Provenance& p) {
  py::dict d;
  d["source_file"] = p.source_file;
  d["importer"] = p.importer;
  d["command_line"] = p.command_line;
  d["created_utc"] = p.created_utc;
  return d;
}

py::dict info_dict(const store::ImageInfo& i) {
  py::dict d;
  d["kind"] = "image";
  d["name"] = i.name;
  d["height"] = i.height;
  d["width"] = i.width;
  d["bands"] = i.bands;
  d["wavelengths"] = wavelengths_array(i.wavelengths);
  d["has_fwhm"] = i.has_fwhm;
  d["units"] = i.units;
  d["valid_pixels"] = i.valid_pixels;
  d["chunk_rows"] = i.chunk_rows;
  d["compression"] = i.compression;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::CollectionInfo& i) {
  py::dict d;
  d["kind"] = "collection";
  d["name"] = i.name;
  d["size"] = i.size;
  d["bands"] = i.bands;
  d["wavelengths"] = wavelengths_array(i.wavelengths);
  d["units"] = i.units;
  d["chunk_rows"] = i.chunk_rows;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::SamplesInfo& i) {
  py::dict d;
  d["kind"] = "samples";
  d["name"] = i.name;
  d["size"] = i.size;
  d["bands"] = i.bands;
  d["wavelengths"] = wavelengths_array(i.wavelengths);
  d["units"] = i.units;
  d["chunk_rows"] = i.chunk_rows;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::GridInfo& i) {
  py::dict d;
  d["kind"] = "grid";
  d["name"] = i.name;
  d["bands"] = i.bands;
  d["wavelengths"] = wavelengths_array(i.wavelengths);
  d["scale"] = i.scale;
  d["units"] = i.units;
  d["compression"] = i.compression;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::CoefficientsInfo& i) {
  py::dict d;
  d["kind"] = "coefficients";
  d["name"] = i.name;
  d["image"] = i.image;
  d["basis"] = i.basis;
  d["method"] = i.method;
  d["height"] = i.height;
  d["width"] = i.width;
  d["k"] = i.k;
  d["valid_pixels"] = i.valid_pixels;
  d["chunk_rows"] = i.chunk_rows;
  d["compression"] = i.compression;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict basis_info(const store::Basis& b, const std::string& name) {
  py::dict d;
  d["kind"] = "basis";
  d["name"] = name;
  d["method"] = b.method;
  d["k"] = b.k();
  d["bands"] = b.bands();
  d["n"] = b.n;
  d["wavelengths"] = wavelengths_array(b.wavelengths);
  d["source"] = b.source;
  d["provenance"] = provenance_dict(b.provenance);
  return d;
}

// The mask of a cube as (H, W) uint8, ones where the store keeps no mask.
py::array_t<std::uint8_t> mask_array(store::Cube& cube) {
  if (cube.mask.empty()) cube.mask.assign(cube.height * cube.width, 1);
  return adopt(std::move(cube.mask), {py::ssize_t(cube.height), py::ssize_t(cube.width)});
}

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
      : reader_(std::move(reader)), depth_(std::max<std::size_t>(1, depth)),
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
      throw UsageError(fmt::format("read: block {} of {}; give 0 to {}", i, reader_->block_count(),
                                   reader_->block_count() - 1));
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
    if (f64_) stream_ = std::make_unique<BlockStream<double>>(reader_, depth_);
    else stream_ = std::make_unique<BlockStream<float>>(reader_, depth_);
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
  throw UsageError(fmt::format("dtype {}: blocks are numpy.float32 or numpy.float64",
                               dt.attr("name").cast<std::string>()));
}

// The names of objects of `kind` (a plural group name) in s.
std::vector<std::string> names_of(const store::Store& s, const std::string& kind) {
  if (kind == "images") return s.images();
  if (kind == "collections") return s.collections();
  if (kind == "samples") return s.samples();
  if (kind == "grids") return s.grids();
  if (kind == "bases") return s.bases();
  return s.coefficients();
}

// The store's current state, with MissingObject (a KeyError) naming the store's full path and what it holds when it
// has no `kind` (plural) called `name`.
const store::Store& holding(const PyStore& ps, const std::string& kind, const std::string& name) {
  const store::Store& s = ps.get();
  const std::vector<std::string> names = names_of(s, kind);
  if (std::find(names.begin(), names.end(), name) != names.end()) return s;
  std::string have;
  for (const auto& n : names) have += (have.empty() ? "" : ", ") + n;
  const std::string one = kind == "bases" ? "basis" : kind == "samples" || kind == "coefficients" ? kind : kind.substr(0, kind.size() - 1);
  throw MissingObject(fmt::format("{}: no {} '{}' (its {}: {})", ps.path().string(), one, name, kind,
                                  have.empty() ? "none" : have));
}

py::array_t<float> image_array(store::Cube&& c, const OptFloat& masked) {
  if (!masked.is_none()) {
    const float fill = masked.cast<float>();
    if (!c.mask.empty())
      for (std::size_t p = 0; p < c.mask.size(); ++p)
        if (!c.mask[p]) std::fill_n(c.data.begin() + std::ptrdiff_t(p * c.bands), c.bands, fill);
  }
  return adopt(std::move(c.data), {py::ssize_t(c.height), py::ssize_t(c.width), py::ssize_t(c.bands)});
}

}  // namespace

void init_store(py::module_& m) {
  py::class_<Blocks>(m, "Blocks",
                     "The valid spectra of a selection in blocks (n x bands arrays, each owned by the caller) that follow "
                     "the storage chunks; the next blocks are read on worker threads while Python works on this one. "
                     "Every iteration (a for loop, list()) is a fresh pass from the first block.")
      .def("__iter__", [](py::object self) {
        self.cast<Blocks&>().rewind();
        return self;
      })
      .def("__next__", &Blocks::next)
      .def("__len__", [](const Blocks& b) { return b.reader().block_count(); })
      .def("__repr__", [](const Blocks& b) {
        const auto& r = b.reader();
        std::string sources;
        for (std::size_t i = 0; i < r.source_names().size() && i < 4; ++i) sources += (i ? ", " : "") + r.source_names()[i];
        if (r.source_names().size() > 4) sources += fmt::format(", ... ({} sources)", r.source_names().size());
        return fmt::format("<specula.Blocks {} blocks, {} spectra x {} bands ({}), {}, from {}>", r.block_count(),
                           r.spectra(), r.bands(), r.wavelengths().describe(), b.f64() ? "float64" : "float32", sources);
      })
      .def("read", &Blocks::read, py::arg("index"), "Block `index` alone (random access).")
      .def_property_readonly("spectra", [](const Blocks& b) { return b.reader().spectra(); }, "Valid spectra in all blocks.")
      .def_property_readonly("bands", [](const Blocks& b) { return b.reader().bands(); })
      .def_property_readonly("block_count", [](const Blocks& b) { return b.reader().block_count(); })
      .def_property_readonly("max_block_spectra", [](const Blocks& b) { return b.reader().max_block_spectra(); })
      .def_property_readonly("wavelengths", [](const Blocks& b) { return wavelengths_array(b.reader().wavelengths()); })
      .def_property_readonly("units", [](const Blocks& b) { return b.reader().units(); })
      .def_property_readonly("sources", [](const Blocks& b) { return b.reader().source_names(); })
      .def_property_readonly("dtype", [](const Blocks& b) {
        return b.f64() ? py::dtype::of<double>() : py::dtype::of<float>();
      })
      .def("block_source", [](const Blocks& b, std::size_t i) { return b.reader().source_names().at(b.reader().block_source(i)); },
           py::arg("index"), "The source (image or collection) block `index` comes from.")
      .def("block_first_row", [](const Blocks& b, std::size_t i) { return b.reader().block_first_row(i); },
           py::arg("index"), "The first row (image row or spectrum) of block `index` in its source.")
      .def("describe_block", [](const Blocks& b, std::size_t i) { return b.reader().describe_block(i); },
           py::arg("index"), "Where block `index` lies, as messages name it.");

  auto list = [](const char* kind) {
    return [kind](const PyStore& ps) { return ps.exists() ? names_of(ps.get(), kind) : std::vector<std::string>{}; };
  };
  py::class_<PyStore>(m, "Store",
                      "A specula store. mode 'r' reads; mode 'a' also writes (the store is created by the first "
                      "commit). Reads see one committed state, refreshed by refresh() and after every commit made "
                      "through this module. `with Store(path, mode='a') as s:` is one transaction: committed on a "
                      "clean exit, abandoned (the store as it was) on an exception; writes outside `with` commit at "
                      "once.")
      .def(py::init([](const PathArg& path, const std::string& mode) { return PyStore(path_from(path), mode); }),
           py::arg("path"), py::arg("mode") = "r")
      .def_property_readonly("path", [](const PyStore& s) { return s.path().string(); }, "The store's absolute path.")
      .def_property_readonly("mode", &PyStore::mode)
      .def_property_readonly("format_version", [](const PyStore& s) { return s.get().format_version(); })
      .def_property_readonly("images", list("images"))
      .def_property_readonly("collections", list("collections"))
      .def_property_readonly("samples", list("samples"))
      .def_property_readonly("grids", list("grids"))
      .def_property_readonly("bases", list("bases"))
      .def_property_readonly("coefficients", list("coefficients"))
      .def("objects",
           [](const PyStore& ps) {
             py::list out;
             if (!ps.exists()) return out;
             const store::Store& s = ps.get();
             for (const auto& [kind, plural] : {std::pair{"image", "images"}, {"collection", "collections"},
                                                {"samples", "samples"}, {"grid", "grids"}, {"basis", "bases"},
                                                {"coefficients", "coefficients"}})
               for (const auto& n : names_of(s, plural)) out.append(py::make_tuple(kind, n));
             return out;
           },
           "Every object as (kind, name) pairs.")
      .def("refresh", &PyStore::refresh, "Reads the latest committed state (what other processes committed since).")
      .def("stale", [](const PyStore& s) { return s.get().stale(); },
           "True when a commit replaced the state this object reads (refresh() to see it).")
      .def("__repr__", [](const PyStore& s) { return fmt::format("<specula.Store '{}' mode='{}'>", s.path().string(), s.mode()); })
      .def("__enter__", [](py::object self) {
        self.cast<PyStore&>().enter();
        return self;
      })
      .def("__exit__",
           [](PyStore& s, const py::object& type, const py::object&, const py::object&) {
             s.exit(type.is_none());
             return false;
           },
           py::arg("exc_type"), py::arg("exc_value"), py::arg("traceback"))
      .def("close", &PyStore::close,
           "Closes the store's files and abandons an open transaction (nothing of it is committed); a later call "
           "reopens the store. Blocks already made keep their own state.")
      .def("info",
           [](const PyStore& ps, const std::string& spec) -> py::dict {
             const store::Store& s = ps.get();
             const auto [kind, name] = resolve(ps, spec);
             if (kind == "images") return info_dict(s.image_info(name));
             if (kind == "collections") return info_dict(s.collection_info(name));
             if (kind == "samples") return info_dict(s.samples_info(name));
             if (kind == "grids") return info_dict(s.grid_info(name));
             if (kind == "bases") return basis_info(s.read_basis(name), name);
             if (kind == "coefficients") return info_dict(s.coefficients_info(name));
             throw UsageError(fmt::format("{}: info: object {} is a {}, which has no info dict", ps.path().string(), spec, kind));
           },
           py::arg("name"), "Metadata of one object: a name, or kind/name when several kinds use it.")
      .def("image",
           [](const PyStore& ps, const std::string& name, const OptFloat& masked) {
             const store::Store& s = holding(ps, "images", name);
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             return image_array(std::move(c), masked);
           },
           py::arg("name"), py::arg("masked") = py::none(),
           "Image `name` as a (height, width, bands) float32 array (a new copy); with masked=v (e.g. numpy.nan) the "
           "spectra of masked pixels are v.")
      .def("mask",
           [](const PyStore& ps, const std::string& name) {
             const store::Store& s = holding(ps, "images", name);
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             return mask_array(c);
           },
           py::arg("name"), "The mask of image `name` as (height, width) uint8, 1 = valid.")
      .def("image_and_mask",
           [](const PyStore& ps, const std::string& name, const OptFloat& masked) {
             const store::Store& s = holding(ps, "images", name);
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             if (c.mask.empty()) c.mask.assign(c.height * c.width, 1);
             std::vector<std::uint8_t> mask = c.mask;
             const py::ssize_t h = py::ssize_t(c.height), w = py::ssize_t(c.width);
             return py::make_tuple(image_array(std::move(c), masked), adopt(std::move(mask), {h, w}));
           },
           py::arg("name"), py::arg("masked") = py::none(), "(image, mask) read once.")
      .def("pixel",
           [](const PyStore& ps, const std::string& name, std::size_t x, std::size_t y) -> OptArrayResult {
             const store::Store& s = holding(ps, "images", name);
             const store::ImageInfo info = s.image_info(name);
             std::vector<float> v(info.bands);
             if (!s.read_pixel(name, x, y, v)) return OptArrayResult(py::none());
             return OptArrayResult(adopt(std::move(v), {py::ssize_t(info.bands)}));
           },
           py::arg("name"), py::arg("x"), py::arg("y"), "The spectrum of pixel (x, y), or None when it is masked.")
      .def("collection",
           [](const PyStore& ps, const std::string& name) {
             store::Collection c = holding(ps, "collections", name).read_collection(name);
             const std::size_t n = c.size(), b = c.bands();
             return adopt(std::move(c.values), {py::ssize_t(n), py::ssize_t(b)});
           },
           py::arg("name"), "Collection `name` as a (size, bands) float32 array.")
      .def("collection_names",
           [](const PyStore& ps, const std::string& name) { return holding(ps, "collections", name).read_collection(name).names; },
           py::arg("name"), "The names of the spectra of collection `name`, in order.")
      .def("samples_data",
           [](const PyStore& ps, const std::string& name, std::size_t first, std::optional<std::size_t> count) {
             const store::Store& s = holding(ps, "samples", name);
             const store::SamplesInfo info = s.samples_info(name);
             if (first > info.size)
               throw UsageError(fmt::format("{}: samples {} hold {} samples; first = {} is beyond them", ps.path().string(),
                                            name, info.size, first));
             const std::size_t n = count ? *count : info.size - first;
             std::vector<double> angles(n * 4);
             std::vector<float> values(n * info.bands);
             {
               py::gil_scoped_release release;
               s.read_samples(name, first, n, angles, values);
             }
             return py::make_tuple(adopt(std::move(angles), {py::ssize_t(n), 4}),
                                   adopt(std::move(values), {py::ssize_t(n), py::ssize_t(info.bands)}));
           },
           py::arg("name"), py::arg("first") = 0, py::arg("count") = py::none(),
           "(angles, values) of samples `name`: (n, 4) float64 theta_i, phi_i, theta_o, phi_o in radians, (n, bands) "
           "float32.")
      .def("grid",
           [](const PyStore& ps, const std::string& name) {
             const store::Store& s = holding(ps, "grids", name);
             py::gil_scoped_release release;
             return s.read_grid(name);
           },
           py::arg("name"), "BRDF grid `name` (a specula.Grid).")
      .def("basis",
           [](const PyStore& ps, const std::string& name) {
             BasisResult b = py::cast(holding(ps, "bases", name).read_basis(name));
             b.attr("_origin") = ps.path().filename().string() + ":" + name;
             return b;
           },
           py::arg("name"), "Basis `name` (a specula.Basis; its origin is 'STORE.h5:NAME').")
      .def("coefficient_map",
           [](const PyStore& ps, const std::string& name) {
             const store::Store& s = holding(ps, "coefficients", name);
             const store::CoefficientsInfo info = s.coefficients_info(name);
             std::vector<float> c(info.height * info.width * info.k);
             std::vector<std::uint8_t> mask(info.height * info.width);
             {
               py::gil_scoped_release release;
               s.read_coefficient_rows(name, 0, info.height, c, mask);
             }
             return py::make_tuple(
                 adopt(std::move(c), {py::ssize_t(info.height), py::ssize_t(info.width), py::ssize_t(info.k)}),
                 adopt(std::move(mask), {py::ssize_t(info.height), py::ssize_t(info.width)}));
           },
           py::arg("name"), "(coefficients (height, width, k) float32, mask (height, width) uint8) of map `name`.")
      .def("coefficient_basis",
           [](const PyStore& ps, const std::string& name) {
             return holding(ps, "coefficients", name).coefficients_basis(name);
           },
           py::arg("name"), "The basis stored with coefficient map `name`.")
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
          py::arg("dtype") = py::none(), py::arg("min_block_pixels") = 32768,
          py::arg("prefetch") = py::none(),
          "Every valid spectrum of the selected images (globs; all when None), or of one collection or samples set, "
          "as a re-iterable specula.Blocks of (n, bands) arrays of `dtype` (numpy.float32, the default, or "
          "numpy.float64).");
}

}  // namespace specula::python
