// The checked matio wrapper of the .mat readers (mat_detail.h): the v5 layout check that runs before matio sizes
// anything from a file, matio's log captured per thread into the exceptions, and the variable helpers.
#include "specula/store/io/mat_detail.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <mutex>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "specula/core/text.h"

namespace specula::store::mat_detail {
namespace {

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
}  // namespace

MatFile::MatFile(const std::filesystem::path& path) : file_(path.string()) {
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
MatFile::~MatFile() {
  if (mat_) Mat_Close(mat_);
}

std::string MatFile::version() const {
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

std::vector<std::string> MatFile::names() {
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
Var MatFile::info(const std::string& name) {
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

Var MatFile::info_or_throw(const std::string& name, const char* role) {
  Var v = info(name);
  if (v) return v;
  std::string list;
  for (const auto& n : names()) list += (list.empty() ? "" : ", ") + n;
  throw InputError(file_ + ": no " + role + "variable '" + name + "' (" +
                   (list.empty() ? std::string("the file has no variables") : "variables: " + list) + ")");
}

Var MatFile::read(const std::string& name) {
  take_matio_message();
  Var v(Mat_VarRead(mat_, name.c_str()));
  if (!v || !v->data) {
    const std::string why = take_matio_message();
    throw LibraryError(file_ + ": matio cannot read the data of variable '" + name + "' (" + version() + " file)" +
                       (why.empty() ? std::string() : ": " + why));
  }
  return v;
}

void MatFile::close() {
  mat_t* m = mat_;
  mat_ = nullptr;
  if (Mat_Close(m) != 0) throw LibraryError(file_ + ": matio failed to close the file: " + take_matio_message());
}

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

void check_data(const MatFile& f, const matvar_t& v, const std::string& name, std::size_t n) {
  const auto size = Mat_SizeOfClass(v.class_type);
  if (size == 0 || static_cast<std::size_t>(v.data_size) != size || v.nbytes / size < n)
    throw LibraryError(f.file() + ": matio returned " + std::to_string(v.nbytes) + " bytes of " +
                       std::to_string(v.data_size) + "-byte elements for variable '" + name + "' (" +
                       std::to_string(n) + " " + class_name(v.class_type) + " values expected)");
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

}  // namespace specula::store::mat_detail
