#pragma once
// The tensor file of Dupuy and Jakob (2018), the container of the RGL material database's .bsdf files, as Mitsuba 3
// (core/tensor.cpp) and pbrt-v4 (util/file.cpp) read it: the 12 bytes "tensor_file\0", version 1.0 as two uint8,
// a uint32 field count, then per field a uint16 name length, the name, a uint16 rank, a uint8 type, a uint64 byte
// offset of the data from the start of the file and rank uint64 extents (row-major, last fastest); little-endian.
// This writer puts every field's data at an offset that is a multiple of 8, in the order the fields are given.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace specula::codec {

/// Magic bytes that open a tensor file (the terminating NUL included).
inline constexpr char kTensorMagic[12] = {'t', 'e', 'n', 's', 'o', 'r', '_', 'f', 'i', 'l', 'e', '\0'};

/// Element types, numbered as Mitsuba's Struct::Type in the published files (uint8 = 1 ... float64 = 11).
enum class TensorType : std::uint8_t {
  uint8 = 1,
  int8,
  uint16,
  int16,
  uint32,
  int32,
  uint64,
  int64,
  float16,
  float32,
  float64
};
/// Bytes of one element of `type`.
std::size_t tensor_type_size(TensorType type);
/// "float32", "uint8", ...
const char* tensor_type_name(TensorType type);

/// One named array: its type, extents and little-endian bytes (product of the extents times the element size).
struct TensorField {
  std::string name;
  TensorType type = TensorType::float32;
  std::vector<std::uint64_t> shape;
  std::vector<std::byte> data;

  /// Number of elements (product of the extents; 1 for rank 0).
  std::uint64_t count() const;
};

/// A whole tensor file: its fields in file order.
struct TensorFile {
  std::vector<TensorField> fields;

  /// The field called `name`, or nullptr.
  const TensorField* find(std::string_view name) const;
};

/// A float32 field of `shape` holding `values` (count must match; else UsageError).
TensorField float32_field(std::string name, std::vector<std::uint64_t> shape, std::span<const float> values);
/// A uint8 field of `shape` holding `values` (count must match; else UsageError).
TensorField uint8_field(std::string name, std::vector<std::uint64_t> shape, std::span<const std::uint8_t> values);
/// The values of a float32 field; InputError naming `label` and the field if it is of another type.
std::vector<float> float32_values(const TensorField& field, const std::string& label);

/// Parses a tensor file held in memory; InputError naming `label` and the problem (magic, version, truncated header,
/// unknown type, a field's data past the end of the file, an extent product that overflows, a repeated name).
TensorFile parse_tensor_file(std::span<const std::byte> bytes, const std::string& label);
/// Reads and parses `path` (label: the file name).
TensorFile read_tensor_file(const std::filesystem::path& path);
/// The bytes of `file` as this writer lays it out; UsageError for an empty or repeated name, a name longer than
/// 65535 bytes or data whose size does not match its shape and type.
std::vector<std::byte> tensor_file_bytes(const TensorFile& file);
/// Writes `file` through a temporary renamed over `path` when complete.
void write_tensor_file(const std::filesystem::path& path, const TensorFile& file);

}  // namespace specula::codec
