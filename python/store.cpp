// specula.Store: a store's objects as numpy arrays and info dicts, and Store.blocks(), the block reader as an
// iterator of numpy blocks read ahead on worker threads with the GIL released.
#include <fmt/format.h>
#include <omp.h>

#include <deque>
#include <future>
#include <variant>

#include "core/error.h"
#include "python/common.h"
#include "store/block_reader.h"

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

// Block i of a reader, read on a worker thread into a buffer the numpy array then owns.
using Block = std::variant<std::unique_ptr<RowMatrixXf>, std::unique_ptr<RowMatrixXd>>;

Block read_block(const store::BlockReader& reader, std::size_t i, bool f64) {
  if (f64) {
    auto m = std::make_unique<RowMatrixXd>();
    reader.read(i, *m);
    return m;
  }
  auto m = std::make_unique<RowMatrixXf>();
  reader.read(i, *m);
  return m;
}

py::array block_array(Block b) {
  return std::visit(
      [](auto&& m) -> py::array {
        using T = typename std::decay_t<decltype(*m)>::Scalar;
        const std::vector<py::ssize_t> shape{py::ssize_t(m->rows()), py::ssize_t(m->cols())};
        const T* data = m->data();
        return adopt<T>(std::move(m), data, shape);
      },
      std::move(b));
}

// The iterator Store.blocks() returns: keeps up to `depth` blocks in flight on worker threads, yields them in order.
class Blocks {
 public:
  Blocks(std::shared_ptr<const store::BlockReader> reader, bool f64, std::size_t depth)
      : reader_(std::move(reader)), f64_(f64), depth_(std::max<std::size_t>(1, depth)) {}
  Blocks(const Blocks&) = delete;
  Blocks& operator=(const Blocks&) = delete;
  ~Blocks() {
    py::gil_scoped_release release;
    queue_.clear();  // waits for reads in flight
  }

  py::array next() {
    if (next_ >= reader_->block_count()) throw py::stop_iteration();
    Block b;
    {
      py::gil_scoped_release release;
      while (issued_ < reader_->block_count() && queue_.size() < depth_) {
        const std::size_t i = issued_++;
        queue_.push_back(std::async(std::launch::async, [r = reader_, i, f = f64_] { return read_block(*r, i, f); }));
      }
      std::future<Block> f = std::move(queue_.front());
      queue_.pop_front();
      ++next_;
      b = f.get();
    }
    return block_array(std::move(b));
  }

  py::array read(std::size_t i) const {
    if (i >= reader_->block_count())
      throw UsageError(fmt::format("read: block {} of {}; give 0 to {}", i, reader_->block_count(),
                                   reader_->block_count() - 1));
    Block b;
    {
      py::gil_scoped_release release;
      b = read_block(*reader_, i, f64_);
    }
    return block_array(std::move(b));
  }

  const store::BlockReader& reader() const { return *reader_; }
  bool f64() const { return f64_; }

 private:
  std::shared_ptr<const store::BlockReader> reader_;
  bool f64_;
  std::size_t depth_;
  std::size_t next_ = 0, issued_ = 0;
  std::deque<std::future<Block>> queue_;
};

bool is_float64(const py::handle& dtype) {
  const py::dtype dt = py::dtype::from_args(py::reinterpret_borrow<py::object>(dtype));
  if (dt.is(py::dtype::of<double>()) || dt.equal(py::dtype::of<double>())) return true;
  if (dt.equal(py::dtype::of<float>())) return false;
  throw UsageError(fmt::format("dtype {}: blocks are numpy.float32 or numpy.float64",
                               dt.attr("name").cast<std::string>()));
}

}  // namespace

void init_store(py::module_& m) {
  py::class_<Blocks>(m, "Blocks",
                     "The valid spectra of a selection in blocks (n x bands arrays) that follow the storage chunks; "
                     "the next blocks are read on worker threads while Python works on this one.")
      .def("__iter__", [](py::object self) { return self; })
      .def("__next__", &Blocks::next)
      .def("__len__", [](const Blocks& b) { return b.reader().block_count(); })
      .def("read", &Blocks::read, py::arg("index"), "Block `index` alone (random access)")
      .def_property_readonly("spectra", [](const Blocks& b) { return b.reader().spectra(); })
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
           py::arg("index"))
      .def("block_first_row", [](const Blocks& b, std::size_t i) { return b.reader().block_first_row(i); },
           py::arg("index"))
      .def("describe_block", [](const Blocks& b, std::size_t i) { return b.reader().describe_block(i); },
           py::arg("index"));

  py::class_<store::Store>(m, "Store", "A specula store opened read-only (one committed state).")
      .def(py::init([](const std::filesystem::path& path) { return store::Store::open(path); }), py::arg("path"))
      .def_property_readonly("path", [](const store::Store& s) { return s.path().string(); })
      .def_property_readonly("format_version", &store::Store::format_version)
      .def_property_readonly("images", &store::Store::images)
      .def_property_readonly("collections", &store::Store::collections)
      .def_property_readonly("samples", &store::Store::samples)
      .def_property_readonly("grids", &store::Store::grids)
      .def_property_readonly("bases", &store::Store::bases)
      .def_property_readonly("coefficients", &store::Store::coefficients)
      .def("objects",
           [](const store::Store& s) {
             py::list out;
             auto add = [&](const char* kind, const std::vector<std::string>& names) {
               for (const auto& n : names) out.append(py::make_tuple(kind, n));
             };
             add("image", s.images());
             add("collection", s.collections());
             add("samples", s.samples());
             add("grid", s.grids());
             add("basis", s.bases());
             add("coefficients", s.coefficients());
             return out;
           },
           "Every object as (kind, name) pairs.")
      .def("stale", &store::Store::stale)
      .def("__repr__", [](const store::Store& s) { return "<specula.Store '" + s.path().string() + "'>"; })
      .def("info",
           [](const store::Store& s, const std::string& spec) -> py::dict {
             const auto [kind, name] = store::resolve_object(s, spec);
             if (kind == "images") return info_dict(s.image_info(name));
             if (kind == "collections") return info_dict(s.collection_info(name));
             if (kind == "samples") return info_dict(s.samples_info(name));
             if (kind == "grids") return info_dict(s.grid_info(name));
             if (kind == "bases") return basis_info(s.read_basis(name), name);
             if (kind == "coefficients") return info_dict(s.coefficients_info(name));
             throw UsageError(fmt::format("{}: info: object {} is a {}, which has no info dict", s.label(), spec, kind));
           },
           py::arg("name"), "Metadata of one object: a name, or kind/name when several kinds use it.")
      .def("image",
           [](const store::Store& s, const std::string& name) {
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             return adopt(std::move(c.data), {py::ssize_t(c.height), py::ssize_t(c.width), py::ssize_t(c.bands)});
           },
           py::arg("name"), "Image `name` as a (height, width, bands) float32 array.")
      .def("mask",
           [](const store::Store& s, const std::string& name) {
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             return mask_array(c);
           },
           py::arg("name"), "The mask of image `name` as (height, width) uint8, 1 = valid.")
      .def("image_and_mask",
           [](const store::Store& s, const std::string& name) {
             store::Cube c;
             {
               py::gil_scoped_release release;
               c = s.read_image(name);
             }
             auto mask = mask_array(c);
             return py::make_tuple(
                 adopt(std::move(c.data), {py::ssize_t(c.height), py::ssize_t(c.width), py::ssize_t(c.bands)}), mask);
           },
           py::arg("name"), "(image, mask) read once.")
      .def("pixel",
           [](const store::Store& s, const std::string& name, std::size_t x, std::size_t y) -> py::object {
             const store::ImageInfo info = s.image_info(name);
             std::vector<float> v(info.bands);
             if (!s.read_pixel(name, x, y, v)) return py::none();
             return adopt(std::move(v), {py::ssize_t(info.bands)});
           },
           py::arg("name"), py::arg("x"), py::arg("y"), "The spectrum of pixel (x, y), or None when it is masked.")
      .def("collection",
           [](const store::Store& s, const std::string& name) {
             store::Collection c = s.read_collection(name);
             const std::size_t n = c.size(), b = c.bands();
             return adopt(std::move(c.values), {py::ssize_t(n), py::ssize_t(b)});
           },
           py::arg("name"), "Collection `name` as a (size, bands) float32 array.")
      .def("collection_names", [](const store::Store& s, const std::string& name) { return s.read_collection(name).names; },
           py::arg("name"), "The names of the spectra of collection `name`, in order.")
      .def("samples_data",
           [](const store::Store& s, const std::string& name, std::size_t first, std::optional<std::size_t> count) {
             const store::SamplesInfo info = s.samples_info(name);
             if (first > info.size)
               throw UsageError(fmt::format("{}: samples {} hold {} samples; first = {} is beyond them", s.label(), name,
                                            info.size, first));
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
           [](const store::Store& s, const std::string& name) {
             py::gil_scoped_release release;
             return s.read_grid(name);
           },
           py::arg("name"), "BRDF grid `name` (a specula.Grid).")
      .def("basis", &store::Store::read_basis, py::arg("name"), "Basis `name` (a specula.Basis).")
      .def("coefficient_map",
           [](const store::Store& s, const std::string& name) {
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
      .def("coefficient_basis", &store::Store::coefficients_basis, py::arg("name"),
           "The basis stored with coefficient map `name`.")
      .def(
          "blocks",
          [](const store::Store& s, const py::object& images, const std::string& collection, const std::string& samples,
             const py::object& dtype, std::size_t min_block_pixels, std::optional<std::size_t> prefetch) {
            const bool f64 = is_float64(dtype);
            const store::Selection sel{.image_globs = globs_from(images), .collection = collection, .samples = samples};
            std::shared_ptr<const store::BlockReader> reader;
            {
              py::gil_scoped_release release;
              reader = std::make_shared<const store::BlockReader>(s, sel, min_block_pixels);
            }
            return std::make_unique<Blocks>(reader, f64,
                                            prefetch ? *prefetch : std::size_t(std::max(2, omp_get_max_threads())));
          },
          py::arg("images") = py::none(), py::arg("collection") = "", py::arg("samples") = "",
          py::arg("dtype") = py::dtype::of<float>(), py::arg("min_block_pixels") = 32768,
          py::arg("prefetch") = py::none(),
          "Every valid spectrum of the selected images (globs; all when None), or of one collection or samples set, "
          "as an iterator of (n, bands) arrays of `dtype` (numpy.float32 or numpy.float64).");
}

}  // namespace specula::python
