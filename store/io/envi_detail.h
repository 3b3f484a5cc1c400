#pragma once
// Inside store/io only: what the ENVI header parser, reader and writer (envi_header.cpp, envi.cpp, envi_write.cpp)
// share.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>

namespace specula::store::envi_detail {

/// One header field's value and the line it starts on.
struct Field {
  std::string value;
  std::size_t line = 0;
};
/// Header fields by lower-case key with single spaces.
using Fields = std::map<std::string, Field, std::less<>>;

/// The fields of header text; InputError prefixed with `filename` when it is not an ENVI header.
Fields parse_fields(std::string_view text, const std::string& filename);
/// Bytes per sample of ENVI data type `data_type` (0 when unsupported).
std::size_t bytes_per_sample(int data_type);
/// The shortest text that reads back as `v`.
std::string format_real(double v);
/// True when `p`'s extension, lower-cased, is `ext`.
bool iequals_ext(const std::filesystem::path& p, std::string_view ext);
/// Rows per block so that one block of the cube (all bands) is about 2 MiB.
std::size_t rows_per_block(std::size_t width, std::size_t bands);

}  // namespace specula::store::envi_detail
