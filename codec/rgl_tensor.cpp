#include "specula/codec/rgl_tensor.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::codec {

static_assert(std::endian::native == std::endian::little, "tensor files are little-endian; add byte swapping");

std::size_t tensor_type_size(TensorType type) {
  switch (type) {
    case TensorType::uint8:
    case TensorType::int8:
      return 1;
    case TensorType::uint16:
    case TensorType::int16:
    case TensorType::float16:
      return 2;
    case TensorType::uint32:
    case TensorType::int32:
    case TensorType::float32:
      return 4;
    case TensorType::uint64:
    case TensorType::int64:
    case TensorType::float64:
      return 8;
  }
  throw UsageError("tensor_type_size: type " + std::to_string(int(type)) + " is not a tensor file type (1-11)");
}

const char* tensor_type_name(TensorType type) {
  static const char* names[] = {"uint8",  "int8",  "uint16",  "int16",   "uint32", "int32",
                                "uint64", "int64", "float16", "float32", "float64"};
  const int t = int(type);
  return t >= 1 && t <= 11 ? names[t - 1] : "invalid";
}

std::uint64_t TensorField::count() const {
  std::uint64_t n = 1;
  for (auto e : shape) n *= e;
  return n;
}

const TensorField* TensorFile::find(std::string_view name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

namespace {
template <class T>
TensorField field_of(std::string name, TensorType type, std::vector<std::uint64_t> shape, std::span<const T> values) {
  TensorField f{std::move(name), type, std::move(shape), {}};
  if (f.count() != values.size())
    throw UsageError("tensor field '" + f.name + "': " + std::to_string(values.size()) + " values for a shape of " +
                     std::to_string(f.count()) + " elements");
  f.data.resize(values.size_bytes());
  if (!values.empty()) std::memcpy(f.data.data(), values.data(), values.size_bytes());
  return f;
}

// Reads fixed-size little-endian values from the header, refusing to run past the end.
struct Cursor {
  std::span<const std::byte> bytes;
  std::size_t at = 0;
  const std::string& label;

  template <class T>
  T get(const char* what) {
    if (bytes.size() - at < sizeof(T))
      throw InputError(label + ": truncated tensor file header: ends in " + what + " at byte " + std::to_string(at));
    T v;
    std::memcpy(&v, bytes.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
};
}  // namespace

TensorField float32_field(std::string name, std::vector<std::uint64_t> shape, std::span<const float> values) {
  return field_of(std::move(name), TensorType::float32, std::move(shape), values);
}

TensorField uint8_field(std::string name, std::vector<std::uint64_t> shape, std::span<const std::uint8_t> values) {
  return field_of(std::move(name), TensorType::uint8, std::move(shape), values);
}

std::vector<float> float32_values(const TensorField& field, const std::string& label) {
  if (field.type != TensorType::float32)
    throw InputError(label + ": field '" + field.name + "' is " + tensor_type_name(field.type) + ", expected float32");
  std::vector<float> v(field.data.size() / sizeof(float));
  if (!v.empty()) std::memcpy(v.data(), field.data.data(), v.size() * sizeof(float));
  return v;
}

TensorFile parse_tensor_file(std::span<const std::byte> bytes, const std::string& label) {
  if (bytes.size() < sizeof(kTensorMagic) + 2 + 4)
    throw InputError(label + ": not a tensor file: " + std::to_string(bytes.size()) +
                     " bytes, fewer than its 18-byte header");
  if (std::memcmp(bytes.data(), kTensorMagic, sizeof(kTensorMagic)) != 0)
    throw InputError(label + ": not a tensor file (.bsdf): it does not start with \"tensor_file\"");
  Cursor c{bytes, sizeof(kTensorMagic), label};
  const auto major = c.get<std::uint8_t>("the version"), minor = c.get<std::uint8_t>("the version");
  if (major != 1 || minor != 0)
    throw InputError(label + ": tensor file version " + std::to_string(major) + "." + std::to_string(minor) +
                     "; only 1.0 is defined");
  const auto n_fields = c.get<std::uint32_t>("the field count");
  // Each field takes at least 13 header bytes: a bound on the count before anything is allocated.
  if (n_fields > (bytes.size() - c.at) / 13)
    throw InputError(label + ": tensor file declares " + std::to_string(n_fields) + " fields, more than its " +
                     std::to_string(bytes.size()) + " bytes can hold");
  TensorFile file;
  std::set<std::string, std::less<>> names;
  for (std::uint32_t i = 0; i < n_fields; ++i) {
    TensorField f;
    const auto name_length = c.get<std::uint16_t>("a field name length");
    if (bytes.size() - c.at < name_length)
      throw InputError(label + ": truncated tensor file header: field " + std::to_string(i) +
                       "'s name runs past the end");
    f.name.assign(reinterpret_cast<const char*>(bytes.data() + c.at), name_length);
    c.at += name_length;
    if (!names.insert(f.name).second)
      throw InputError(label + ": tensor field '" + printable(f.name) + "' appears twice");
    const auto rank = c.get<std::uint16_t>("a field rank");
    const auto type = c.get<std::uint8_t>("a field type");
    if (type < 1 || type > 11)
      throw InputError(label + ": tensor field '" + printable(f.name) + "' has type " + std::to_string(type) +
                       "; types are 1 (uint8) to 11 (float64)");
    f.type = TensorType(type);
    const auto offset = c.get<std::uint64_t>("a field offset");
    std::uint64_t count = 1;
    for (std::uint16_t d = 0; d < rank; ++d) {
      const auto e = c.get<std::uint64_t>("a field extent");
      if (e != 0 && count > std::numeric_limits<std::uint64_t>::max() / 8 / e)
        throw InputError(label + ": tensor field '" + printable(f.name) + "': its extents overflow 64 bits");
      count *= e;
      f.shape.push_back(e);
    }
    const std::uint64_t size = count * tensor_type_size(f.type);
    if (offset > bytes.size() || size > bytes.size() - offset)
      throw InputError(label + ": tensor field '" + printable(f.name) + "' (" + std::to_string(size) +
                       " bytes at offset " + std::to_string(offset) + ") runs past the end of the " +
                       std::to_string(bytes.size()) + "-byte file; truncated?");
    f.data.assign(bytes.begin() + std::ptrdiff_t(offset), bytes.begin() + std::ptrdiff_t(offset + size));
    file.fields.push_back(std::move(f));
  }
  return file;
}

TensorFile read_tensor_file(const std::filesystem::path& path) {
  const std::string label = path.filename().string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(label + ": is a directory, not a tensor file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(label + ": cannot open (" + std::strerror(errno) + ")");
  std::vector<std::byte> bytes;
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  in.seekg(0);
  if (size < 0) throw InputError(label + ": cannot tell its size");
  bytes.resize(std::size_t(size));
  in.read(reinterpret_cast<char*>(bytes.data()), size);
  if (!in) throw InputError(label + ": read error (" + std::strerror(errno) + ")");
  return parse_tensor_file(bytes, label);
}

std::vector<std::byte> tensor_file_bytes(const TensorFile& file) {
  std::set<std::string, std::less<>> names;
  std::size_t header = sizeof(kTensorMagic) + 2 + 4;
  for (const auto& f : file.fields) {
    if (f.name.empty() || f.name.size() > 65535 || !names.insert(f.name).second)
      throw UsageError("tensor file: field name '" + f.name + "' is empty, longer than 65535 bytes or repeated");
    if (f.shape.size() > 65535) throw UsageError("tensor field '" + f.name + "': rank above 65535");
    if (f.data.size() != f.count() * tensor_type_size(f.type))
      throw UsageError("tensor field '" + f.name + "': " + std::to_string(f.data.size()) + " bytes for " +
                       std::to_string(f.count()) + " " + tensor_type_name(f.type) + " elements");
    header += 2 + f.name.size() + 2 + 1 + 8 + 8 * f.shape.size();
  }
  auto align = [](std::size_t n) { return (n + 7) / 8 * 8; };
  std::vector<std::uint64_t> offsets;
  std::size_t end = align(header);
  for (const auto& f : file.fields) {
    offsets.push_back(end);
    end = align(end + f.data.size());
  }
  std::vector<std::byte> out(end, std::byte{0});
  std::size_t at = 0;
  auto put = [&](const void* p, std::size_t n) {
    std::memcpy(out.data() + at, p, n);
    at += n;
  };
  put(kTensorMagic, sizeof(kTensorMagic));
  const std::uint8_t version[2] = {1, 0};
  put(version, 2);
  const auto n = std::uint32_t(file.fields.size());
  put(&n, 4);
  for (std::size_t i = 0; i < file.fields.size(); ++i) {
    const auto& f = file.fields[i];
    const auto len = std::uint16_t(f.name.size()), rank = std::uint16_t(f.shape.size());
    const auto type = std::uint8_t(f.type);
    put(&len, 2);
    put(f.name.data(), f.name.size());
    put(&rank, 2);
    put(&type, 1);
    put(&offsets[i], 8);
    for (auto e : f.shape) put(&e, 8);
  }
  for (std::size_t i = 0; i < file.fields.size(); ++i)
    if (!file.fields[i].data.empty())
      std::memcpy(out.data() + offsets[i], file.fields[i].data.data(), file.fields[i].data.size());
  return out;
}

void write_tensor_file(const std::filesystem::path& path, const TensorFile& file) {
  const auto bytes = tensor_file_bytes(file);
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    f.flush();
    if (!f) throw LibraryError(path.string() + ": write failed (" + std::strerror(errno) + ")");
  }
  out.commit();
}

}  // namespace specula::codec
