#pragma once
// Inside store/io only: matio behind a checked wrapper for the .mat readers (mat.cpp): a file whose v5 layout is
// checked before matio sizes anything from it, variables owned, matio's messages in the exceptions, and the typed
// access to a variable's data.
#include <matio.h>

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "specula/core/error.h"

namespace specula::store::mat_detail {

/// The most elements a variable may promise (1 TiB of float32).
constexpr std::uint64_t kMaxElements = (std::uint64_t{1} << 40) / sizeof(float);

struct VarFree {
  void operator()(matvar_t* v) const { Mat_VarFree(v); }
};
using Var = std::unique_ptr<matvar_t, VarFree>;

/// A .mat file open in matio; every failure an InputError or LibraryError naming the file.
class MatFile {
 public:
  /// Opens `path` after checking its v5 layout; throws InputError when it is missing or not a readable .mat file.
  explicit MatFile(const std::filesystem::path& path);
  MatFile(const MatFile&) = delete;
  MatFile& operator=(const MatFile&) = delete;
  ~MatFile();

  const std::string& file() const { return file_; }
  /// "v7.3", "v5/v7", "v4" or "unknown version".
  std::string version() const;
  /// The variables' names (those with control characters left out).
  std::vector<std::string> names();
  /// The variable's header only, or null when the file has no such variable.
  Var info(const std::string& name);
  /// The variable's header; throws InputError listing the variables when it is absent (`role`: "mask " or "").
  Var info_or_throw(const std::string& name, const char* role);
  /// The variable with its data.
  Var read(const std::string& name);
  /// Closes the file, throwing what matio reports.
  void close();

 private:
  std::string file_;
  mat_t* mat_ = nullptr;
};

/// The name of a matio class as messages give it ("double", "a struct").
const char* class_name(matio_classes c);
/// double, single, uint8, uint16 or int16.
bool supported_class(matio_classes c);
/// "rows x cols x ...".
std::string dims_text(const matvar_t& v);
/// The product of the dimensions (UINT64_MAX on overflow).
std::uint64_t element_count(const matvar_t& v);
/// Throws InputError unless the variable is real and of a supported class.
void check_numeric(const MatFile& f, const matvar_t& v, const std::string& name);
/// Throws unless a read variable holds at least n elements (a corrupt file's dimensions may promise more).
void check_data(const MatFile& f, const matvar_t& v, const std::string& name, std::size_t n);

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

/// A real variable of a supported class.
bool numeric(const matvar_t& v);
/// A 2-D variable with one dimension 1 and some elements.
bool is_vector(const matvar_t& v);
/// The first n values of variable `name` as doubles.
std::vector<double> read_doubles(MatFile& mf, const std::string& name, std::size_t n);

/// A variable's header.
struct Entry {
  std::string name;
  Var head;
};
/// Every variable's header, in file order.
std::vector<Entry> scan(MatFile& mf);
/// The first of `names` (lower case) that a variable's name matches case-insensitively, or null.
const Entry* find_ci(const std::vector<Entry>& all, std::initializer_list<const char*> names);
/// "variables: a, b" or "the file has no variables".
std::string list_names(const std::vector<Entry>& all);

}  // namespace specula::store::mat_detail
