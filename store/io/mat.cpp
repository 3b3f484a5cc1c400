#include "specula/store/io/mat.h"

#include <matio.h>
#include <zlib.h>

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

namespace specula::store {
namespace {

constexpr std::uint64_t kMaxElements = (std::uint64_t{1} << 40) / sizeof(float);

thread_local std::string t_matio_message;

void capture_matio_log(int level, char* message) {
  if (!(level & (MATIO_LOG_LEVEL_ERROR | MATIO_LOG_LEVEL_CRITICAL | MATIO_LOG_LEVEL_WARNING)) || !message) return;
  if (!t_matio_message.empty()) t_matio_message += "; ";
  t_matio_message += message;
}

void install_matio_log() {
  static std::once_flag once;
  static int status = 0;
  std::call_once(once, [] { status = Mat_LogInitFunc("specula", capture_matio_log); });
  if (status != 0) throw LibraryError("matio: Mat_LogInitFunc failed with status " + std::to_string(status));
}

std::string take_matio_message() {
  std::string m = std::move(t_matio_message);
  t_matio_message.clear();
  for (char& c : m)
    if (c == '\n' || c == '\r') c = ' ';
  return m;
}

struct VarFree {
  void operator()(matvar_t* v) const { Mat_VarFree(v); }
};
using Var = std::unique_ptr<matvar_t, VarFree>;

// MATLAB v5 data types used below.
constexpr std::uint32_t kMiMatrix = 14, kMiCompressed = 15;

// matio sizes its buffers from a v5 file's tags before reading what they announce, so a few corrupt bytes could
// make it allocate and clear gigabytes. Checked first: each top-level element fits in the file; the array flags,
// dimensions and name opening each matrix (inside compressed elements too, from their first inflated bytes) fit
// in the matrix and stay small (rank up to 32, names up to 4096 bytes); and a numeric matrix's real part holds as
// many values as its dimensions promise. v7.3 (HDF5) files are left to matio; files without the MAT-file header
// (v4, which matio would also read, as trustingly) are refused.
class V5Layout {
 public:
  V5Layout(const std::string& file, std::istream& in, std::uint64_t size) : file_(file), in_(in), size_(size) {}

  void check() {
    char header[128];
    const bool read = size_ >= 128 && in_.read(header, 128);
    const std::string endian = read ? std::string(header + 126, 2) : std::string();
    if (endian != "IM" && endian != "MI")
      throw InputError(file_ +
                       ": not a MATLAB .mat file in v5 or v7.3 format (no 128-byte MAT-file header; v4 files "
                       "are not read); save it from MATLAB with save(..., '-v7') or '-v7.3'");
    swap_ = endian == "MI";
    if (u16(reinterpret_cast<const unsigned char*>(header) + 124) != 0x0100) return;  // 0x0200: v7.3
    for (std::uint64_t at = 128; at + 8 <= size_;) {
      unsigned char tag[8];
      in_.seekg(std::streamoff(at));
      if (!in_.read(reinterpret_cast<char*>(tag), 8)) return;
      const std::uint32_t type = u32(tag), n = u32(tag + 4);
      if (n > size_ - at - 8) corrupt(at, n, size_ - at - 8);
      if (type == kMiMatrix) {
        std::vector<unsigned char> head(std::min<std::uint64_t>(n, kHead));
        in_.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size()));
        matrix(head, n, at + 8);
      } else if (type == kMiCompressed) {
        inflated_matrix(at + 8, n);
      }
      at += 8 + n + (type == kMiCompressed ? 0 : (8 - n % 8) % 8);
    }
  }

 private:
  static constexpr std::size_t kHead = 4096;

  std::uint16_t u16(const unsigned char* p) const {
    return swap_ ? std::uint16_t(p[0] << 8 | p[1]) : std::uint16_t(p[1] << 8 | p[0]);
  }
  std::uint32_t u32(const unsigned char* p) const {
    return swap_ ? std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | p[3]
                 : std::uint32_t(p[3]) << 24 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[1]) << 8 | p[0];
  }

  [[noreturn]] void corrupt(std::uint64_t at, std::uint64_t claims, std::uint64_t room) const {
    throw InputError(file_ + ": corrupt MATLAB v5 file: the element at byte " + std::to_string(at) + " claims " +
                     std::to_string(claims) + " bytes where " + std::to_string(room) +
                     " can follow; the file is truncated or damaged, save it again");
  }

  // The flags, dims and name sub-elements opening a matrix of n bytes whose first bytes are `head`, and for a
  // numeric class the real part's element count against the dimensions.
  void matrix(const std::vector<unsigned char>& head, std::uint64_t n, std::uint64_t at) const {
    std::uint64_t pos = 0, promised = 1;
    int array_class = 0;
    for (const std::uint64_t cap : {std::uint64_t{16}, std::uint64_t{8 * 32}, std::uint64_t{4096}, n}) {
      if (pos + 8 > head.size()) return;
      const std::uint32_t type = u32(head.data() + pos);
      const bool small = (type >> 16) != 0;  // small data element: size in the upper half, data in the tag
      const std::uint64_t len = small ? type >> 16 : u32(head.data() + pos + 4);
      const std::uint64_t room = n - std::min(n, pos + (small ? 4 : 8));
      if (len > std::min(room, cap)) corrupt(at + pos, len, std::min(room, cap));
      const unsigned char* data = head.data() + pos + (small ? 4 : 8);
      if (cap == 16 && len >= 4 && data + 4 <= head.data() + head.size()) array_class = data[swap_ ? 3 : 0];
      if (cap == 8 * 32)
        for (std::uint64_t k = 0; k + 4 <= len && data + k + 4 <= head.data() + head.size(); k += 4)
          if (__builtin_mul_overflow(promised, std::uint64_t{u32(data + k)}, &promised)) promised = UINT64_MAX;
      if (cap == n && array_class >= 6 && array_class <= 15) {  // mxDOUBLE_CLASS ... mxUINT64_CLASS
        const std::uint32_t t = small ? type & 0xffff : type;
        const std::uint64_t size = t == 1 || t == 2    ? 1
                                   : t == 3 || t == 4  ? 2
                                   : t >= 5 && t <= 7  ? 4
                                   : t == 9 || t >= 12 ? 8
                                                       : 0;
        if (size != 0 && t <= 13 && len / size != promised)
          throw InputError(file_ + ": corrupt MATLAB v5 file: the variable at byte " + std::to_string(at) +
                           " has dimensions for " + std::to_string(promised) + " values but its data holds " +
                           std::to_string(len / size) + "; the file is truncated or damaged, save it again");
      }
      pos += small ? 8 : 8 + len + (8 - len % 8) % 8;
    }
  }

  void inflated_matrix(std::uint64_t at, std::uint32_t n) {
    std::vector<unsigned char> packed(std::min<std::uint64_t>(n, kHead)), out(kHead);
    in_.seekg(std::streamoff(at));
    in_.read(reinterpret_cast<char*>(packed.data()), std::streamsize(packed.size()));
    z_stream z{};
    if (inflateInit(&z) != Z_OK) return;
    z.next_in = packed.data();
    z.avail_in = uInt(in_.gcount());
    z.next_out = out.data();
    z.avail_out = uInt(out.size());
    inflate(&z, Z_SYNC_FLUSH);
    out.resize(out.size() - z.avail_out);
    inflateEnd(&z);
    if (out.size() < 8 || u32(out.data()) != kMiMatrix) return;
    matrix(std::vector<unsigned char>(out.begin() + 8, out.end()), u32(out.data() + 4), at);
  }

  const std::string& file_;
  std::istream& in_;
  std::uint64_t size_;
  bool swap_ = false;
};

class MatFile {
 public:
  explicit MatFile(const std::filesystem::path& path) : file_(path.string()) {
    install_matio_log();
    take_matio_message();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      throw InputError(file_ + ": no such file; give the path of a MATLAB .mat file");
    {
      std::ifstream in(path, std::ios::binary);
      V5Layout(file_, in, std::filesystem::file_size(path, ec)).check();
    }
    mat_ = Mat_Open(file_.c_str(), MAT_ACC_RDONLY);
    if (!mat_) {
      const std::string why = take_matio_message();
      throw InputError(file_ + ": not a MATLAB .mat file that matio can read" +
                       (why.empty() ? std::string() : " (matio: " + why + ")") +
                       "; save it from MATLAB with save(..., '-v7') or '-v7.3'");
    }
  }
  MatFile(const MatFile&) = delete;
  MatFile& operator=(const MatFile&) = delete;
  ~MatFile() {
    if (mat_) Mat_Close(mat_);
  }

  const std::string& file() const { return file_; }

  std::string version() const {
    switch (Mat_GetVersion(mat_)) {
      case MAT_FT_MAT73:
        return "v7.3";
      case MAT_FT_MAT5:
        return "v5/v7";
      case MAT_FT_MAT4:
        return "v4";
      default:
        return "unknown version";
    }
  }

  std::vector<std::string> names() {
    std::size_t n = 0;
    char** dir = Mat_GetDir(mat_, &n);
    std::vector<std::string> out;
    if (!dir) {
      take_matio_message();
      return out;
    }
    // A name with control characters cannot come from MATLAB and would break one-line messages: such
    // variables are not offered.
    for (std::size_t i = 0; i < n; ++i)
      if (dir[i] &&
          std::none_of(dir[i], dir[i] + std::strlen(dir[i]), [](char c) { return (c >= 0 && c < 0x20) || c == 0x7f; }))
        out.emplace_back(dir[i]);
    return out;
  }

  // The variable's header only, or null when the file has no such variable.
  Var info(const std::string& name) {
    take_matio_message();
    Var v(Mat_VarReadInfo(mat_, name.c_str()));
    if (!v) {
      const std::string why = take_matio_message();
      for (const auto& n : names())
        if (n == name)
          throw LibraryError(file_ + ": matio cannot read variable '" + name + "'" +
                             (why.empty() ? std::string() : ": " + why));
    }
    return v;
  }

  Var info_or_throw(const std::string& name, const char* role) {
    Var v = info(name);
    if (v) return v;
    std::string list;
    for (const auto& n : names()) list += (list.empty() ? "" : ", ") + n;
    throw InputError(file_ + ": no " + role + "variable '" + name + "' (" +
                     (list.empty() ? std::string("the file has no variables") : "variables: " + list) + ")");
  }

  Var read(const std::string& name) {
    take_matio_message();
    Var v(Mat_VarRead(mat_, name.c_str()));
    if (!v || !v->data) {
      const std::string why = take_matio_message();
      throw LibraryError(file_ + ": matio cannot read the data of variable '" + name + "' (" + version() + " file)" +
                         (why.empty() ? std::string() : ": " + why));
    }
    return v;
  }

  void close() {
    mat_t* m = mat_;
    mat_ = nullptr;
    if (Mat_Close(m) != 0) throw LibraryError(file_ + ": matio failed to close the file: " + take_matio_message());
  }

 private:
  std::string file_;
  mat_t* mat_ = nullptr;
};

const char* class_name(matio_classes c) {
  switch (c) {
    case MAT_C_EMPTY:
      return "empty";
    case MAT_C_CELL:
      return "a cell array";
    case MAT_C_STRUCT:
      return "a struct";
    case MAT_C_OBJECT:
      return "an object";
    case MAT_C_CHAR:
      return "char";
    case MAT_C_SPARSE:
      return "sparse";
    case MAT_C_DOUBLE:
      return "double";
    case MAT_C_SINGLE:
      return "single";
    case MAT_C_INT8:
      return "int8";
    case MAT_C_UINT8:
      return "uint8";
    case MAT_C_INT16:
      return "int16";
    case MAT_C_UINT16:
      return "uint16";
    case MAT_C_INT32:
      return "int32";
    case MAT_C_UINT32:
      return "uint32";
    case MAT_C_INT64:
      return "int64";
    case MAT_C_UINT64:
      return "uint64";
    case MAT_C_FUNCTION:
      return "a function handle";
    case MAT_C_OPAQUE:
      return "opaque";
  }
  return "unknown";
}

bool supported_class(matio_classes c) {
  return c == MAT_C_DOUBLE || c == MAT_C_SINGLE || c == MAT_C_UINT8 || c == MAT_C_UINT16 || c == MAT_C_INT16;
}

std::string dims_text(const matvar_t& v) {
  std::string s;
  for (int i = 0; i < v.rank; ++i) s += (i ? " x " : "") + std::to_string(v.dims[i]);
  return s;
}

std::uint64_t element_count(const matvar_t& v) {
  std::uint64_t n = 1;
  for (int i = 0; i < v.rank; ++i)
    if (__builtin_mul_overflow(n, std::uint64_t{v.dims[i]}, &n)) return UINT64_MAX;
  return n;
}

void check_numeric(const MatFile& f, const matvar_t& v, const std::string& name) {
  if (!supported_class(v.class_type))
    throw InputError(f.file() + ": variable '" + name + "' is " + class_name(v.class_type) +
                     "; convert it to double, single, uint8, uint16 or int16");
  if (v.isComplex)
    throw InputError(f.file() + ": variable '" + name + "' is complex; store its real part (real(" + name + "))");
}

// Throws unless a read variable holds at least n elements (a corrupt file's dimensions may promise more).
void check_data(const MatFile& f, const matvar_t& v, const std::string& name, std::size_t n) {
  const auto size = Mat_SizeOfClass(v.class_type);
  if (size == 0 || static_cast<std::size_t>(v.data_size) != size || v.nbytes / size < n)
    throw LibraryError(f.file() + ": matio returned " + std::to_string(v.nbytes) + " bytes of " +
                       std::to_string(v.data_size) + "-byte elements for variable '" + name + "' (" +
                       std::to_string(n) + " " + class_name(v.class_type) + " values expected)");
}

// Calls fn(p) with the typed data pointer of a read variable holding at least n elements.
template <typename Fn>
void visit_data(const MatFile& f, const matvar_t& v, const std::string& name, std::size_t n, Fn&& fn) {
  check_data(f, v, name, n);
  switch (v.class_type) {
    case MAT_C_DOUBLE:
      fn(static_cast<const double*>(v.data));
      break;
    case MAT_C_SINGLE:
      fn(static_cast<const float*>(v.data));
      break;
    case MAT_C_UINT8:
      fn(static_cast<const std::uint8_t*>(v.data));
      break;
    case MAT_C_UINT16:
      fn(static_cast<const std::uint16_t*>(v.data));
      break;
    case MAT_C_INT16:
      fn(static_cast<const std::int16_t*>(v.data));
      break;
    default:
      throw UsageError("visit_data: unsupported class " + std::string(class_name(v.class_type)));
  }
}

bool numeric(const matvar_t& v) { return supported_class(v.class_type) && !v.isComplex; }
bool is_vector(const matvar_t& v) { return v.rank == 2 && (v.dims[0] == 1 || v.dims[1] == 1) && element_count(v) > 0; }

std::vector<double> read_doubles(MatFile& mf, const std::string& name, std::size_t n) {
  const Var v = mf.read(name);
  std::vector<double> out(n);
  visit_data(mf, *v, name, n, [&](const auto* p) {
    for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<double>(p[i]);
  });
  return out;
}

// Every variable's header, in file order.
struct Entry {
  std::string name;
  Var head;
};
std::vector<Entry> scan(MatFile& mf) {
  std::vector<Entry> out;
  for (const auto& n : mf.names()) {
    Var v = mf.info(n);
    if (v) out.push_back({n, std::move(v)});
  }
  return out;
}

const Entry* find_ci(const std::vector<Entry>& all, std::initializer_list<const char*> names) {
  for (const char* want : names)
    for (const auto& e : all)
      if (lower(e.name) == want) return &e;
  return nullptr;
}

std::string list_names(const std::vector<Entry>& all) {
  std::string list;
  for (const auto& e : all) list += (list.empty() ? "" : ", ") + e.name;
  return list.empty() ? std::string("the file has no variables") : "variables: " + list;
}

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
