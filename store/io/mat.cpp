#include "specula/store/io/mat.h"

#include <matio.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "specula/core/error.h"

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

class MatFile {
 public:
  explicit MatFile(const std::filesystem::path& path) : file_(path.string()) {
    install_matio_log();
    take_matio_message();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      throw InputError(file_ + ": no such file; give the path of a MATLAB .mat file");
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
      case MAT_FT_MAT73: return "v7.3";
      case MAT_FT_MAT5: return "v5/v7";
      case MAT_FT_MAT4: return "v4";
      default: return "unknown version";
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
    for (std::size_t i = 0; i < n; ++i)
      if (dir[i]) out.emplace_back(dir[i]);
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
    case MAT_C_EMPTY: return "empty";
    case MAT_C_CELL: return "a cell array";
    case MAT_C_STRUCT: return "a struct";
    case MAT_C_OBJECT: return "an object";
    case MAT_C_CHAR: return "char";
    case MAT_C_SPARSE: return "sparse";
    case MAT_C_DOUBLE: return "double";
    case MAT_C_SINGLE: return "single";
    case MAT_C_INT8: return "int8";
    case MAT_C_UINT8: return "uint8";
    case MAT_C_INT16: return "int16";
    case MAT_C_UINT16: return "uint16";
    case MAT_C_INT32: return "int32";
    case MAT_C_UINT32: return "uint32";
    case MAT_C_INT64: return "int64";
    case MAT_C_UINT64: return "uint64";
    case MAT_C_FUNCTION: return "a function handle";
    case MAT_C_OPAQUE: return "opaque";
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

// Calls fn(p) with the typed data pointer of a read variable holding at least n elements.
template <typename Fn>
void visit_data(const MatFile& f, const matvar_t& v, const std::string& name, std::size_t n, Fn&& fn) {
  const auto size = Mat_SizeOfClass(v.class_type);
  if (size == 0 || static_cast<std::size_t>(v.data_size) != size || v.nbytes < n * size)
    throw LibraryError(f.file() + ": matio returned " + std::to_string(v.nbytes) + " bytes of " +
                       std::to_string(v.data_size) + "-byte elements for variable '" + name + "' (" +
                       std::to_string(n) + " " + class_name(v.class_type) + " values expected)");
  switch (v.class_type) {
    case MAT_C_DOUBLE: fn(static_cast<const double*>(v.data)); break;
    case MAT_C_SINGLE: fn(static_cast<const float*>(v.data)); break;
    case MAT_C_UINT8: fn(static_cast<const std::uint8_t*>(v.data)); break;
    case MAT_C_UINT16: fn(static_cast<const std::uint16_t*>(v.data)); break;
    case MAT_C_INT16: fn(static_cast<const std::int16_t*>(v.data)); break;
    default:
      throw UsageError("visit_data: unsupported class " + std::string(class_name(v.class_type)));
  }
}

}  // namespace

Cube read_mat(const std::filesystem::path& path, const std::string& var,
              const std::optional<std::string>& mask_var, const WavelengthGrid& wavelengths) {
  MatFile mf(path);
  const std::string& file = mf.file();

  const Var head = mf.info_or_throw(var, "");
  check_numeric(mf, *head, var);
  if (head->rank < 2 || head->rank > 3)
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) +
                     "; expected rows x cols x bands (3-D)");
  const std::size_t rows = head->dims[0], cols = head->dims[1], bands = head->rank == 3 ? head->dims[2] : 1;
  const std::uint64_t n = element_count(*head);
  if (n == 0) throw InputError(file + ": variable '" + var + "' is empty (" + dims_text(*head) + ")");
  if (n > kMaxElements)
    throw InputError(file + ": variable '" + var + "' is " + dims_text(*head) +
                     ", more than the 1 TiB limit for one image; split it");

  Cube cube;
  cube.provenance.source_file = path.string();
  cube.provenance.importer = "mat";

  // A usable "wavelengths" or "bands" variable wins; an unusable one is an error unless a grid was passed.
  bool have_grid = false;
  std::string wl_problem;
  for (const std::string wl_name : {"wavelengths", "bands"}) {
    if (wl_name == var || (mask_var && wl_name == *mask_var)) continue;
    const Var wi = mf.info(wl_name);
    if (!wi) continue;
    if (!supported_class(wi->class_type) || wi->isComplex || element_count(*wi) != bands) {
      wl_problem = file + ": variable '" + wl_name + "' is " + (wi->isComplex ? "complex " : "") +
                   class_name(wi->class_type) + " " + dims_text(*wi) + " but '" + var + "' has " +
                   std::to_string(bands) + " bands; store one wavelength in nm per band or give the `wavelengths` option";
      break;
    }
    const Var wv = mf.read(wl_name);
    std::vector<double> nm(bands);
    visit_data(mf, *wv, wl_name, bands, [&](const auto* p) {
      for (std::size_t i = 0; i < bands; ++i) nm[i] = static_cast<double>(p[i]);
    });
    cube.wavelengths = WavelengthGrid(std::move(nm), file + ": variable '" + wl_name + "'");
    have_grid = true;
    break;
  }
  if (!have_grid) {
    if (wavelengths.empty())
      throw InputError(!wl_problem.empty()
                           ? wl_problem
                           : file + ": no 'wavelengths' or 'bands' variable; give the `wavelengths` option FIRST:LAST:STEP for the " +
                                 std::to_string(bands) + " bands of '" + var + "'");
    if (wavelengths.size() != bands)
      throw InputError(file + ": variable '" + var + "' has " + std::to_string(bands) + " bands but the `wavelengths` option gives " +
                       std::to_string(wavelengths.size()) + "; pass one wavelength per band");
    cube.wavelengths = wavelengths;
  }

  std::vector<std::uint8_t> mask;
  if (mask_var) {
    const Var mi = mf.info_or_throw(*mask_var, "mask ");
    check_numeric(mf, *mi, *mask_var);
    const bool shape_ok = (mi->rank == 2 || (mi->rank == 3 && mi->dims[2] == 1)) && mi->dims[0] == rows &&
                          mi->dims[1] == cols;
    if (!shape_ok)
      throw InputError(file + ": mask variable '" + *mask_var + "' is " + dims_text(*mi) + " but '" + var + "' is " +
                       std::to_string(rows) + " x " + std::to_string(cols) + " pixels; give a rows x cols mask");
    const Var mv = mf.read(*mask_var);
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
  cube.resize(rows, cols, bands);
  float* out = cube.data.data();
  visit_data(mf, *data, var, static_cast<std::size_t>(n), [&](const auto* p) {
    for (std::size_t b = 0; b < bands; ++b)
      for (std::size_t c = 0; c < cols; ++c)
        for (std::size_t r = 0; r < rows; ++r) out[(r * cols + c) * bands + b] = static_cast<float>(*p++);
  });
  cube.mask = std::move(mask);
  mf.close();
  return cube;
}

}  // namespace specula::store
