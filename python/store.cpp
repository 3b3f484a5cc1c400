// specula.Store: a store's objects as numpy arrays and info dicts (Store.blocks() is in blocks.cpp, the writes in
// store_write.cpp).
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include <algorithm>

#include "python/common.h"
#include "specula/core/error.h"
#include "specula/store/info_json.h"

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

py::dict named(const char* kind, const std::string& name) {
  py::dict d;
  d["kind"] = kind;
  d["name"] = name;
  return d;
}

template <class Info>
void add_spectral(py::dict& d, const Info& i) {
  d["bands"] = i.bands;
  d["wavelengths"] = wavelengths_array(i.wavelengths);
}

// The closing fields of the info dicts of images and coefficient maps.
template <class Info>
void add_chunked(py::dict& d, const Info& i) {
  d["valid_pixels"] = i.valid_pixels;
  d["chunk_rows"] = i.chunk_rows;
  d["compression"] = i.compression;
  d["provenance"] = provenance_dict(i.provenance);
}

py::dict info_dict(const store::ImageInfo& i) {
  py::dict d = named("image", i.name);
  d["height"] = i.height;
  d["width"] = i.width;
  add_spectral(d, i);
  d["has_fwhm"] = i.has_fwhm;
  d["units"] = i.units;
  add_chunked(d, i);
  return d;
}

// Collections and samples: lists of spectra.
template <class Info>
py::dict list_dict(const char* kind, const Info& i) {
  py::dict d = named(kind, i.name);
  d["size"] = i.size;
  add_spectral(d, i);
  d["units"] = i.units;
  d["chunk_rows"] = i.chunk_rows;
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::CollectionInfo& i) { return list_dict("collection", i); }

py::dict info_dict(const store::SamplesInfo& i) { return list_dict("samples", i); }

// The parameterisation of a grid's source .bsdf: None, or what `info --json` gives for it (store/info_json.h).
py::object parameterisation_dict(const store::GridInfo& i) {
  if (!i.parameterisation) return py::none();
  return py::module_::import("json").attr("loads")(store::grid_json(i)["parameterisation"].dump());
}

py::dict info_dict(const store::GridInfo& i) {
  py::dict d = named("grid", i.name);
  add_spectral(d, i);
  d["scale"] = i.scale;
  d["units"] = i.units;
  d["compression"] = i.compression;
  d["parameterisation"] = parameterisation_dict(i);
  d["provenance"] = provenance_dict(i.provenance);
  return d;
}

py::dict info_dict(const store::CoefficientsInfo& i) {
  py::dict d = named("coefficients", i.name);
  d["image"] = i.image;
  d["basis"] = i.basis;
  d["method"] = i.method;
  d["height"] = i.height;
  d["width"] = i.width;
  d["k"] = i.k;
  add_chunked(d, i);
  return d;
}

py::dict basis_info(const store::Basis& b, const std::string& name) {
  py::dict d = named("basis", name);
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

std::vector<std::string> names_of(const store::Store& s, const std::string& kind) {
  if (kind == "images") return s.images();
  if (kind == "collections") return s.collections();
  if (kind == "samples") return s.samples();
  if (kind == "grids") return s.grids();
  if (kind == "bases") return s.bases();
  return s.coefficients();
}

const store::Store& holding(const PyStore& ps, const std::string& kind, const std::string& name) {
  const store::Store& s = ps.get();
  const std::vector<std::string> names = names_of(s, kind);
  if (std::find(names.begin(), names.end(), name) != names.end()) return s;
  std::string have;
  for (const auto& n : names) have += (have.empty() ? "" : ", ") + n;
  const std::string one = kind == "bases"                               ? "basis"
                          : kind == "samples" || kind == "coefficients" ? kind
                                                                        : kind.substr(0, kind.size() - 1);
  throw MissingObject(
      fmt::format("{}: no {} '{}' (its {}: {})", ps.path().string(), one, name, kind, have.empty() ? "none" : have));
}

namespace {

// Image `name` of the store, read without holding the GIL.
store::Cube read_image(const PyStore& ps, const std::string& name) {
  const store::Store& s = holding(ps, "images", name);
  py::gil_scoped_release release;
  return s.read_image(name);
}

// Opening, refreshing and closing; transactions through `with`.
void def_state(py::class_<PyStore>& cls) {
  cls.def(py::init([](const PathArg& path, const std::string& mode) { return PyStore(path_from(path), mode); }),
          py::arg("path"), py::arg("mode") = "r")
      .def_property_readonly(
          "path", [](const PyStore& s) { return s.path().string(); }, "The store's absolute path.")
      .def_property_readonly("mode", &PyStore::mode)
      .def_property_readonly("format_version", [](const PyStore& s) { return s.get().format_version(); })
      .def("refresh", &PyStore::refresh, "Reads the latest committed state (what other processes committed since).")
      .def(
          "stale", [](const PyStore& s) { return s.get().stale(); },
          "True when a commit replaced the state this object reads (refresh() to see it).")
      .def("__repr__",
           [](const PyStore& s) { return fmt::format("<specula.Store '{}' mode='{}'>", s.path().string(), s.mode()); })
      .def("__enter__",
           [](py::object self) {
             self.cast<PyStore&>().enter();
             return self;
           })
      .def(
          "__exit__",
          [](PyStore& s, const py::object& type, const py::object&, const py::object&) {
            s.exit(type.is_none());
            return false;
          },
          py::arg("exc_type"), py::arg("exc_value"), py::arg("traceback"))
      .def("close", &PyStore::close,
           "Closes the store's files and abandons an open transaction (nothing of it is committed); a later call "
           "reopens the store. Blocks already made keep their own state.");
}

// What the store holds: object lists, (kind, name) pairs and info dicts.
void def_listing(py::class_<PyStore>& cls) {
  auto list = [](const char* kind) {
    return [kind](const PyStore& ps) { return ps.exists() ? names_of(ps.get(), kind) : std::vector<std::string>{}; };
  };
  cls.def_property_readonly("images", list("images"))
      .def_property_readonly("collections", list("collections"))
      .def_property_readonly("samples", list("samples"))
      .def_property_readonly("grids", list("grids"))
      .def_property_readonly("bases", list("bases"))
      .def_property_readonly("coefficients", list("coefficients"))
      .def(
          "objects",
          [](const PyStore& ps) {
            py::list out;
            if (!ps.exists()) return out;
            const store::Store& s = ps.get();
            for (const auto& [kind, plural] : {std::pair{"image", "images"},
                                               {"collection", "collections"},
                                               {"samples", "samples"},
                                               {"grid", "grids"},
                                               {"basis", "bases"},
                                               {"coefficients", "coefficients"}})
              for (const auto& n : names_of(s, plural)) out.append(py::make_tuple(kind, n));
            return out;
          },
          "Every object as (kind, name) pairs.")
      .def(
          "info",
          [](const PyStore& ps, const std::string& spec) -> py::dict {
            const store::Store& s = ps.get();
            const auto [kind, name] = resolve(ps, spec);
            if (kind == "images") return info_dict(s.image_info(name));
            if (kind == "collections") return info_dict(s.collection_info(name));
            if (kind == "samples") return info_dict(s.samples_info(name));
            if (kind == "grids") return info_dict(s.grid_info(name));
            if (kind == "bases") return basis_info(s.read_basis(name), name);
            if (kind == "coefficients") return info_dict(s.coefficients_info(name));
            throw UsageError(
                fmt::format("{}: info: object {} is a {}, which has no info dict", ps.path().string(), spec, kind));
          },
          py::arg("name"), "Metadata of one object: a name, or kind/name when several kinds use it.");
}

// Images, their masks and single pixels.
void def_images(py::class_<PyStore>& cls) {
  cls.def(
         "image",
         [](const PyStore& ps, const std::string& name, const OptFloat& masked) {
           store::Cube c = read_image(ps, name);
           return image_array(std::move(c), masked);
         },
         py::arg("name"), py::arg("masked") = py::none(),
         "Image `name` as a (height, width, bands) float32 array (a new copy); with masked=v (e.g. numpy.nan) the "
         "spectra of masked pixels are v.")
      .def(
          "mask",
          [](const PyStore& ps, const std::string& name) {
            store::Cube c = read_image(ps, name);
            return mask_array(c);
          },
          py::arg("name"), "The mask of image `name` as (height, width) uint8, 1 = valid.")
      .def(
          "image_and_mask",
          [](const PyStore& ps, const std::string& name, const OptFloat& masked) {
            store::Cube c = read_image(ps, name);
            if (c.mask.empty()) c.mask.assign(c.height * c.width, 1);
            std::vector<std::uint8_t> mask = c.mask;
            const py::ssize_t h = py::ssize_t(c.height), w = py::ssize_t(c.width);
            return py::make_tuple(image_array(std::move(c), masked), adopt(std::move(mask), {h, w}));
          },
          py::arg("name"), py::arg("masked") = py::none(), "(image, mask) read once.")
      .def(
          "pixel",
          [](const PyStore& ps, const std::string& name, std::size_t x, std::size_t y) -> OptArrayResult {
            const store::Store& s = holding(ps, "images", name);
            const store::ImageInfo info = s.image_info(name);
            std::vector<float> v(info.bands);
            if (!s.read_pixel(name, x, y, v)) return OptArrayResult(py::none());
            return OptArrayResult(adopt(std::move(v), {py::ssize_t(info.bands)}));
          },
          py::arg("name"), py::arg("x"), py::arg("y"), "The spectrum of pixel (x, y), or None when it is masked.");
}

// Collections, samples, grids, bases and coefficient maps.
void def_objects(py::class_<PyStore>& cls) {
  cls.def(
         "collection",
         [](const PyStore& ps, const std::string& name) {
           store::Collection c = holding(ps, "collections", name).read_collection(name);
           const std::size_t n = c.size(), b = c.bands();
           return adopt(std::move(c.values), {py::ssize_t(n), py::ssize_t(b)});
         },
         py::arg("name"), "Collection `name` as a (size, bands) float32 array.")
      .def(
          "collection_names",
          [](const PyStore& ps, const std::string& name) {
            return holding(ps, "collections", name).read_collection(name).names;
          },
          py::arg("name"), "The names of the spectra of collection `name`, in order.")
      .def(
          "samples_data",
          [](const PyStore& ps, const std::string& name, std::size_t first, std::optional<std::size_t> count) {
            const store::Store& s = holding(ps, "samples", name);
            const store::SamplesInfo info = s.samples_info(name);
            if (first > info.size)
              throw UsageError(fmt::format("{}: samples {} hold {} samples; first = {} is beyond them",
                                           ps.path().string(), name, info.size, first));
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
      .def(
          "grid",
          [](const PyStore& ps, const std::string& name) {
            const store::Store& s = holding(ps, "grids", name);
            py::gil_scoped_release release;
            return s.read_grid(name);
          },
          py::arg("name"), "BRDF grid `name` (a specula.Grid).")
      .def(
          "basis",
          [](const PyStore& ps, const std::string& name) {
            BasisResult b = py::cast(holding(ps, "bases", name).read_basis(name));
            b.attr("_origin") = ps.path().filename().string() + ":" + name;
            return b;
          },
          py::arg("name"), "Basis `name` (a specula.Basis; its origin is 'STORE.h5:NAME').")
      .def(
          "coefficient_map",
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
      .def(
          "coefficient_basis",
          [](const PyStore& ps, const std::string& name) {
            return holding(ps, "coefficients", name).coefficients_basis(name);
          },
          py::arg("name"), "The basis stored with coefficient map `name`.");
}

}  // namespace

void init_store(py::module_& m) {
  py::class_<PyStore> cls(
      m, "Store",
      "A specula store. mode 'r' reads; mode 'a' also writes (the store is created by the first "
      "commit). Reads see one committed state, refreshed by refresh() and after every commit made "
      "through this module. `with Store(path, mode='a') as s:` is one transaction: committed on a "
      "clean exit, abandoned (the store as it was) on an exception; writes outside `with` commit at "
      "once.");
  def_state(cls);
  def_listing(cls);
  def_images(cls);
  def_objects(cls);
}

}  // namespace specula::python
