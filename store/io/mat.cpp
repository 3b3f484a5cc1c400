#include "specula/store/io/mat.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/core/text.h"
#include "specula/store/io/mat_detail.h"

namespace specula::store {
using namespace mat_detail;
namespace {

// The file's wavelength vector: name, length and values in nm (empty values when it is band numbering).
struct FileGrid {
  std::string name;
  std::size_t length = 0;
  std::vector<double> nm;
  bool numbering = false;
};

std::optional<FileGrid> file_grid(MatFile& mf, const std::vector<Entry>& all) {
  for (const char* want : {"wavelength", "wavelengths", "bands", "wl", "lambda"})
    for (const auto& e : all) {
      if (lower(e.name) != want) continue;
      FileGrid g{e.name, static_cast<std::size_t>(element_count(*e.head)), {}, false};
      if (!numeric(*e.head) || !is_vector(*e.head)) return g;  // unusable: length checks will name it
      g.nm = read_doubles(mf, e.name, g.length);
      bool numbering = true, integers = true, micrometres = true;
      for (std::size_t i = 0; i < g.nm.size(); ++i) {
        const double v = g.nm[i];
        numbering = numbering && v == double(i + 1);
        integers = integers && v == std::floor(v);
        micrometres = micrometres && v >= 0.2 && v <= 20;
      }
      if (numbering && g.length > 1) {
        g.numbering = true;
        g.nm.clear();
      } else if (micrometres && !integers) {
        for (double& v : g.nm) v *= 1000.0;
      }
      return g;
    }
  return std::nullopt;
}

std::optional<double> scalar(MatFile& mf, const std::vector<Entry>& all, const char* name) {
  const Entry* e = find_ci(all, {name});
  if (!e || !numeric(*e->head) || element_count(*e->head) != 1) return std::nullopt;
  return read_doubles(mf, e->name, 1)[0];
}

enum class Order { hwb, bhw, bp, pb };

struct Layout {
  std::string var;
  Order order = Order::hwb;
  std::size_t rows = 0, cols = 0, bands = 0;
  std::uint64_t n = 0;
};

// The cube variable when none was named, or nullopt when the file has no candidate.
std::optional<std::string> detect_cube_var(const MatFile& mf, const std::vector<Entry>& all) {
  std::vector<std::string> cubes;
  for (const auto& e : all)
    if (e.head->rank == 3 && numeric(*e.head)) cubes.push_back(e.name);
  if (cubes.size() == 1) return cubes.front();
  if (cubes.size() > 1) {
    for (const char* known : {"ref", "rad", "cube", "reflectances", "data"})
      for (const auto& c : cubes)
        if (c == known) return c;
    std::string list;
    for (const auto& c : cubes) list += (list.empty() ? "" : ", ") + c;
    throw InputError(
        mf.file() + ": several 3-D variables (" + list +
        ") and none of the known names ref, rad, cube, reflectances, data; give its name as the `var` option");
  }
  return std::nullopt;
}

// The nRow/nCol matrix variable (given or detected) when the file has both scalars.
std::optional<std::string> detect_matrix_var(const std::vector<Entry>& all, std::size_t pixels) {
  if (const Entry* y = find_ci(all, {"y"}); y && y->head->rank == 2) return y->name;
  std::optional<std::string> found;
  for (const auto& e : all)
    if (e.head->rank == 2 && numeric(*e.head) && (e.head->dims[0] == pixels || e.head->dims[1] == pixels)) {
      if (found) return std::nullopt;
      found = e.name;
    }
  return found;
}

Layout image_layout(MatFile& mf, const std::vector<Entry>& all, const std::string& var_in, std::size_t nwl) {
  const std::string& file = mf.file();
  const auto nrow = scalar(mf, all, "nrow"), ncol = scalar(mf, all, "ncol");
  const bool benchmark = nrow && ncol && *nrow >= 1 && *ncol >= 1;
  if (benchmark)
    for (const auto& [name, v] : {std::pair{"nRow", *nrow}, std::pair{"nCol", *ncol}})
      if (v != std::floor(v) || v > double(std::uint64_t{1} << 31))
        throw InputError(file + ": " + name + " = " + num(v) +
                         " is not a whole number of pixels up to 2^31; store the image's row and column counts");
  std::string var = var_in;
  if (var.empty()) {
    if (auto c = detect_cube_var(mf, all)) {
      var = *c;
    } else if (benchmark) {
      auto m = detect_matrix_var(all, static_cast<std::size_t>(*nrow) * static_cast<std::size_t>(*ncol));
      if (!m)
        throw InputError(file + ": nRow and nCol but no matrix 'Y' of bands x nRow*nCol pixels (" + list_names(all) +
                         "); give its name as the `var` option");
      var = *m;
    } else {
      throw InputError(file + ": no 3-D image variable (" + list_names(all) + "); give its name as the `var` option");
    }
  }
  const Var head = mf.info_or_throw(var, "");
  check_numeric(mf, *head, var);
  Layout l;
  l.var = var;
  l.n = element_count(*head);
  if (head->rank == 3) {
    const std::size_t d0 = head->dims[0], d1 = head->dims[1], d2 = head->dims[2];
    if (nwl != 0 && d0 == nwl && d2 != nwl) {
      l.order = Order::bhw;
      l.bands = d0, l.rows = d1, l.cols = d2;
    } else {
      l.rows = d0, l.cols = d1, l.bands = d2;
    }
  } else if (head->rank == 2 && benchmark) {
    const std::size_t r = static_cast<std::size_t>(*nrow), c = static_cast<std::size_t>(*ncol), px = r * c;
    l.rows = r, l.cols = c;
    if (head->dims[1] == px && head->dims[0] != px) {
      l.order = Order::bp, l.bands = head->dims[0];
    } else if (head->dims[0] == px) {
      l.order = Order::pb, l.bands = head->dims[1];
    } else {
      throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) +
                       " but nRow x nCol = " + std::to_string(r) + " x " + std::to_string(c) + " = " +
                       std::to_string(px) + " pixels; give a bands x pixels matrix");
    }
  } else if (head->rank == 2) {
    l.rows = head->dims[0], l.cols = head->dims[1], l.bands = 1;
  } else {
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) + "; expected rows x cols x bands (3-D)");
  }
  if (l.n == 0) throw InputError(file + ": variable '" + var + "' is empty (" + dims_text(*head) + ")");
  if (l.n > kMaxElements)
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) +
                     ", more than the 1 TiB limit for one image; split it");
  return l;
}

// The wavelengths of a variable's bands and the band of the variable at each of them (ascending).
struct BandGrid {
  WavelengthGrid grid;
  std::vector<std::size_t> order;
};

// `nm` (one per band of a variable, listed by `list`) sorted, the bands permuted with them.
BandGrid sorted_grid(const std::vector<double>& nm, const std::string& file, const std::string& list) {
  std::vector<std::size_t> order = ascending_band_order(nm, [&](std::size_t first, std::size_t second) {
    throw InputError(file + ": variable '" + list + "' lists wavelength " + num(nm[second]) + " nm twice (bands " +
                     std::to_string(first + 1) + " and " + std::to_string(second + 1) + "); remove one of them");
  });
  std::vector<double> sorted;
  for (const std::size_t b : order) sorted.push_back(nm[b]);
  return {WavelengthGrid(std::move(sorted), file + ": variable '" + list + "'"), std::move(order)};
}

// Each spectrum of `values` (spectra x bands, band fastest) rearranged so band k holds its band order[k].
void permute_bands(std::span<float> values, const std::vector<std::size_t>& order) {
  const std::size_t bands = order.size();
  bool identity = true;
  for (std::size_t k = 0; k < bands; ++k) identity = identity && order[k] == k;
  if (identity) return;
  std::vector<float> spectrum(bands);
  for (std::size_t at = 0; at < values.size(); at += bands) {
    std::copy_n(values.begin() + std::ptrdiff_t(at), bands, spectrum.begin());
    for (std::size_t k = 0; k < bands; ++k) values[at + k] = spectrum[order[k]];
  }
}

// The grid of `bands` bands of `var`: the file's vector (any order), else the argument (through a kept-band list).
BandGrid resolve_grid(MatFile& mf, const std::vector<Entry>& all, const std::optional<FileGrid>& fg,
                      const std::string& var, std::size_t bands, const WavelengthGrid& given) {
  const std::string& file = mf.file();
  std::string problem;
  if (fg && !fg->numbering && !fg->nm.empty() && fg->length == bands) return sorted_grid(fg->nm, file, fg->name);
  if (fg) {
    const Entry* e = find_ci(all, {lower(fg->name).c_str()});
    problem = fg->numbering
                  ? file + ": variable '" + fg->name + "' holds band numbers 1.." + std::to_string(fg->length) +
                        ", not wavelengths; give the `wavelengths` option FIRST:LAST:STEP for the " +
                        std::to_string(bands) + " bands of '" + var + "'"
                  : file + ": variable '" + fg->name + "' is " + (e->head->isComplex ? "complex " : "") +
                        class_name(e->head->class_type) + " " + dims_text(*e->head) + " but '" + var + "' has " +
                        std::to_string(bands) +
                        " bands; store one wavelength in nm per band or give the `wavelengths` option";
  }
  if (given.empty())
    throw InputError(!problem.empty()
                         ? problem
                         : file + ": no wavelength variable (wavelength, wavelengths, bands, wl or lambda) for the " +
                               std::to_string(bands) + " bands of '" + var +
                               "'; give the `wavelengths` option FIRST:LAST:STEP");
  if (given.size() == bands) return sorted_grid({given.values().begin(), given.values().end()}, file, var);
  if (const Entry* sel = find_ci(all, {"slectbands", "selectbands"});
      sel && numeric(*sel->head) && is_vector(*sel->head) && element_count(*sel->head) == bands) {
    const auto idx = read_doubles(mf, sel->name, bands);
    std::vector<double> nm(bands);
    for (std::size_t i = 0; i < bands; ++i) {
      if (idx[i] < 1 || idx[i] > double(given.size()) || idx[i] != std::floor(idx[i]))
        throw InputError(file + ": variable '" + sel->name + "' holds band " + std::to_string(idx[i]) +
                         " but the `wavelengths` option gives " + std::to_string(given.size()) +
                         "; pass the full grid the 1-based band numbers refer to");
      nm[i] = given[static_cast<std::size_t>(idx[i]) - 1];
    }
    return sorted_grid(nm, file, sel->name);
  }
  throw InputError(file + ": variable '" + var + "' has " + std::to_string(bands) +
                   " bands but the `wavelengths` option gives " + std::to_string(given.size()) +
                   "; pass one wavelength per band");
}

// The 2-D library matrix (given or detected), or nullopt when there is none.
std::optional<std::string> detect_library_var(const std::vector<Entry>& all, const std::optional<FileGrid>& fg) {
  if (const Entry* d = find_ci(all, {"data"}); d && d->head->rank == 2) return d->name;
  std::optional<std::string> found;
  for (const auto& e : all)
    if (e.head->rank == 2 && numeric(*e.head) && !is_vector(*e.head) && (!fg || e.name != fg->name)) {
      if (found) return std::nullopt;
      found = e.name;
    }
  return found;
}

}  // namespace

MatKind mat_kind(const std::filesystem::path& path, const std::string& var) {
  MatFile mf(path);
  const auto all = scan(mf);
  if (find_ci(all, {"nrow"}) && find_ci(all, {"ncol"})) return MatKind::image;
  std::optional<std::string> name = var;
  if (var.empty()) {
    for (const auto& e : all)
      if (e.head->rank == 3 && numeric(*e.head)) return MatKind::image;
  }
  const auto fg = file_grid(mf, all);
  if (!fg || fg->nm.empty()) return MatKind::image;
  if (var.empty()) name = detect_library_var(all, fg);
  if (!name) return MatKind::image;
  const Entry* e = nullptr;
  for (const auto& x : all)
    if (x.name == *name) e = &x;
  if (!e || e->head->rank != 2 || !numeric(*e->head)) return MatKind::image;
  const bool fits = e->head->dims[0] == fg->length || e->head->dims[1] == fg->length;
  return fits && element_count(*e->head) > fg->length ? MatKind::collection : MatKind::image;
}

namespace {
// out[(r * cols + c) * bands + b] = in[r + rows * (c + cols * b)] (MATLAB's column-major H x W x B to band-fastest
// rows), by tiles of rows x columns whose input and output lines stay in cache, tiles spread over the threads.
template <class T>
void transpose_column_major(const T* in, std::size_t rows, std::size_t cols, std::size_t bands, float* out) {
  constexpr std::size_t kTileRows = 64, kTileCols = 8;
  const std::size_t row_tiles = (rows + kTileRows - 1) / kTileRows, col_tiles = (cols + kTileCols - 1) / kTileCols;
  parallel_for(
      row_tiles * col_tiles,
      [&](std::size_t t) {
        const std::size_t r0 = (t / col_tiles) * kTileRows, c0 = (t % col_tiles) * kTileCols;
        const std::size_t r1 = std::min(rows, r0 + kTileRows), c1 = std::min(cols, c0 + kTileCols);
        for (std::size_t b = 0; b < bands; ++b)
          for (std::size_t c = c0; c < c1; ++c) {
            const T* src = in + rows * (c + cols * b);
            for (std::size_t r = r0; r < r1; ++r) out[(r * cols + c) * bands + b] = static_cast<float>(src[r]);
          }
      },
      16);
}
}  // namespace

std::uint64_t mat_decoded_bytes(const std::filesystem::path& path) {
  MatFile mf(path);
  std::uint64_t total = 0;
  for (const auto& e : scan(mf))
    if (numeric(*e.head)) {
      const std::uint64_t n = element_count(*e.head);
      total += n == UINT64_MAX ? n : n * (Mat_SizeOfClass(e.head->class_type) + sizeof(float));
    }
  return total;
}

Cube read_mat(const std::filesystem::path& path, const std::string& var_in, const std::optional<std::string>& mask_var,
              const WavelengthGrid& wavelengths) {
  MatFile mf(path);
  const std::string& file = mf.file();
  std::vector<Entry> all = scan(mf);
  if (!var_in.empty() || mask_var) {  // the named variables are never the wavelength vector
    std::erase_if(all, [&](const Entry& e) { return e.name == var_in || (mask_var && e.name == *mask_var); });
  }
  const auto fg = file_grid(mf, all);
  const std::size_t nwl = fg && !fg->numbering && !fg->nm.empty() ? fg->length : wavelengths.size();
  const Layout l = image_layout(mf, scan(mf), var_in, nwl);
  const std::string& var = l.var;
  const std::size_t rows = l.rows, cols = l.cols, bands = l.bands;

  Cube cube;
  cube.provenance.source_file = path.string();
  cube.provenance.importer = "mat";
  BandGrid bg = resolve_grid(mf, all, fg, var, bands, wavelengths);
  cube.wavelengths = std::move(bg.grid);

  std::vector<std::uint8_t> mask;
  if (mask_var) {
    const Var mi = mf.info_or_throw(*mask_var, "mask ");
    check_numeric(mf, *mi, *mask_var);
    const bool shape_ok =
        (mi->rank == 2 || (mi->rank == 3 && mi->dims[2] == 1)) && mi->dims[0] == rows && mi->dims[1] == cols;
    if (!shape_ok)
      throw InputError(file + ": mask variable '" + *mask_var + "' is " + dims_text(*mi) + " but '" + var + "' is " +
                       std::to_string(rows) + " x " + std::to_string(cols) + " pixels; give a rows x cols mask");
    const Var mv = mf.read(*mask_var);
    check_data(mf, *mv, *mask_var, rows * cols);
    mask.resize(rows * cols);
    visit_data(mf, *mv, *mask_var, rows * cols, [&](const auto* p) {
      for (std::size_t c = 0; c < cols; ++c)
        for (std::size_t r = 0; r < rows; ++r) {
          const double v = static_cast<double>(*p++);
          mask[r * cols + c] = (v != 0 && !std::isnan(v)) ? 1 : 0;
        }
    });
  }

  const Var data = mf.read(var);
  check_data(mf, *data, var, static_cast<std::size_t>(l.n));  // before allocating what the dimensions promise
  cube.resize(rows, cols, bands);
  float* out = cube.data.data();
  visit_data(mf, *data, var, static_cast<std::size_t>(l.n), [&](const auto* p) {
    switch (l.order) {
      case Order::hwb:  // (r, c, b) at r + rows * (c + cols * b)
      case Order::pb:   // (p, b) at p + pixels * b, p = r + rows * c: the same
        transpose_column_major(p, rows, cols, bands, out);
        break;
      case Order::bhw:  // (b, r, c) at b + bands * (r + rows * c)
        for (std::size_t c = 0; c < cols; ++c)
          for (std::size_t r = 0; r < rows; ++r)
            for (std::size_t b = 0; b < bands; ++b) out[(r * cols + c) * bands + b] = static_cast<float>(*p++);
        break;
      case Order::bp:  // (b, p) at b + bands * p, p = r + rows * c
        for (std::size_t c = 0; c < cols; ++c)
          for (std::size_t r = 0; r < rows; ++r)
            for (std::size_t b = 0; b < bands; ++b) out[(r * cols + c) * bands + b] = static_cast<float>(*p++);
        break;
    }
  });
  permute_bands(cube.data, bg.order);
  cube.mask = std::move(mask);
  mf.close();
  return cube;
}

Collection read_mat_collection(const std::filesystem::path& path, const std::string& var_in,
                               const WavelengthGrid& wavelengths) {
  MatFile mf(path);
  const std::string& file = mf.file();
  std::vector<Entry> all = scan(mf);
  if (!var_in.empty()) std::erase_if(all, [&](const Entry& e) { return e.name == var_in; });
  const auto fg = file_grid(mf, all);
  std::string var = var_in;
  if (var.empty()) {
    auto d = detect_library_var(all, fg);
    if (!d)
      throw InputError(file + ": no 2-D spectra matrix 'data' (" + list_names(all) +
                       "); give its name as the `var` option");
    var = *d;
  }
  const Var head = mf.info_or_throw(var, "");
  check_numeric(mf, *head, var);
  if (head->rank != 2 || element_count(*head) == 0)
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) + "; expected bands x spectra (2-D)");
  if (element_count(*head) > kMaxElements)
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) +
                     ", more than the 1 TiB limit; split it");
  const std::size_t d0 = head->dims[0], d1 = head->dims[1];
  const std::size_t nwl = fg && !fg->numbering && !fg->nm.empty() ? fg->length : wavelengths.size();
  const bool columns = nwl == 0 || d0 == nwl || d1 != nwl;  // ISETCam: one spectrum per column
  const std::size_t bands = columns ? d0 : d1, count = columns ? d1 : d0;

  Collection col;
  BandGrid bg = resolve_grid(mf, all, fg, var, bands, wavelengths);
  col.wavelengths = std::move(bg.grid);
  col.provenance.source_file = path.string();
  col.provenance.importer = "mat";
  const Var data = mf.read(var);
  check_data(mf, *data, var, count * bands);  // before allocating what the dimensions promise
  col.names.reserve(count);
  for (std::size_t j = 0; j < count; ++j) col.names.push_back(var + "_" + std::to_string(j + 1));
  col.values.resize(count * bands);
  visit_data(mf, *data, var, count * bands, [&](const auto* p) {
    for (std::size_t i = 0; i < count * bands; ++i) {
      // element i is (i % d0, i / d0); spectrum j band k
      const std::size_t a = i % d0, b = i / d0;
      const std::size_t j = columns ? b : a, k = columns ? a : b;
      col.values[j * bands + k] = static_cast<float>(p[i]);
    }
  });
  permute_bands(col.values, bg.order);
  mf.close();
  return col;
}

}  // namespace specula::store
