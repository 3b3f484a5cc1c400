// The tensor file container against files assembled byte by byte here, and the layout the writer gives.
#include "specula/codec/rgl_tensor.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "specula/core/error.h"

namespace specula::codec {
namespace {

// Appends little-endian values to a byte vector.
struct Bytes {
  std::vector<std::byte> b;
  template <class T>
  Bytes& put(T v) {
    const auto at = b.size();
    b.resize(at + sizeof(T));
    std::memcpy(b.data() + at, &v, sizeof(T));
    return *this;
  }
  Bytes& str(std::string_view s) {
    for (char c : s) b.push_back(std::byte(c));
    return *this;
  }
  Bytes& pad(std::size_t to) {
    b.resize(to, std::byte{0});
    return *this;
  }
};

// A two-field file: "a" uint8 [3] at offset 72 and "bc" float32 [2, 1] at offset 80.
Bytes hand_made() {
  Bytes f;
  f.str(std::string_view("tensor_file\0", 12)).put<std::uint8_t>(1).put<std::uint8_t>(0).put<std::uint32_t>(2);
  f.put<std::uint16_t>(1).str("a").put<std::uint16_t>(1).put<std::uint8_t>(1).put<std::uint64_t>(72).put<std::uint64_t>(
      3);
  f.put<std::uint16_t>(2).str("bc").put<std::uint16_t>(2).put<std::uint8_t>(10).put<std::uint64_t>(80);
  f.put<std::uint64_t>(2).put<std::uint64_t>(1);
  EXPECT_EQ(f.b.size(), 71u);
  f.pad(72).put<std::uint8_t>(7).put<std::uint8_t>(8).put<std::uint8_t>(9).pad(80).put(1.5f).put(-2.25f);
  return f;
}

TEST(RglTensor, ParsesAHandMadeFile) {
  const TensorFile t = parse_tensor_file(hand_made().b, "hand.bsdf");
  ASSERT_EQ(t.fields.size(), 2u);
  const TensorField* a = t.find("a");
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->type, TensorType::uint8);
  EXPECT_EQ(a->shape, std::vector<std::uint64_t>{3});
  EXPECT_EQ(std::to_integer<int>(a->data[2]), 9);
  const TensorField* bc = t.find("bc");
  ASSERT_NE(bc, nullptr);
  EXPECT_EQ(bc->shape, (std::vector<std::uint64_t>{2, 1}));
  EXPECT_EQ(float32_values(*bc, "hand.bsdf"), (std::vector<float>{1.5f, -2.25f}));
  EXPECT_THROW(float32_values(*a, "hand.bsdf"), InputError);
  EXPECT_EQ(t.find("missing"), nullptr);
}

TEST(RglTensor, WriterLaysFieldsOutAlignedInOrder) {
  TensorFile t;
  const std::uint8_t a[] = {7, 8, 9};
  const float bc[] = {1.5f, -2.25f};
  t.fields.push_back(uint8_field("a", {3}, a));
  t.fields.push_back(float32_field("bc", {2, 1}, bc));
  // Header: 18 + (2 + 1 + 2 + 1 + 8 + 8) + (2 + 2 + 2 + 1 + 8 + 16) = 71 -> data at 72, then 72 + 3 -> 80.
  const auto bytes = tensor_file_bytes(t);
  ASSERT_EQ(bytes.size(), 88u);
  Bytes expect;
  expect.str(std::string_view("tensor_file\0", 12)).put<std::uint8_t>(1).put<std::uint8_t>(0).put<std::uint32_t>(2);
  expect.put<std::uint16_t>(1)
      .str("a")
      .put<std::uint16_t>(1)
      .put<std::uint8_t>(1)
      .put<std::uint64_t>(72)
      .put<std::uint64_t>(3);
  expect.put<std::uint16_t>(2).str("bc").put<std::uint16_t>(2).put<std::uint8_t>(10).put<std::uint64_t>(80);
  expect.put<std::uint64_t>(2).put<std::uint64_t>(1);
  expect.pad(72).put<std::uint8_t>(7).put<std::uint8_t>(8).put<std::uint8_t>(9).pad(80).put(1.5f).put(-2.25f);
  EXPECT_EQ(bytes, expect.b);
  // And the file read back is the file written.
  const auto path = std::filesystem::temp_directory_path() /
                    ("rgl_tensor_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".bsdf");
  write_tensor_file(path, t);
  const TensorFile back = read_tensor_file(path);
  std::filesystem::remove(path);
  ASSERT_EQ(back.fields.size(), 2u);
  EXPECT_EQ(back.fields[1].data, t.fields[1].data);
  EXPECT_EQ(back.fields[0].name, "a");
}

TEST(RglTensor, TypesHaveTheirSizes) {
  EXPECT_EQ(tensor_type_size(TensorType::uint8), 1u);
  EXPECT_EQ(tensor_type_size(TensorType::float16), 2u);
  EXPECT_EQ(tensor_type_size(TensorType::uint32), 4u);
  EXPECT_EQ(tensor_type_size(TensorType::float32), 4u);
  EXPECT_EQ(tensor_type_size(TensorType::float64), 8u);
  EXPECT_STREQ(tensor_type_name(TensorType::float32), "float32");
}

std::string error_of(const std::vector<std::byte>& b) {
  try {
    parse_tensor_file(b, "bad.bsdf");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RglTensor, MalformedFilesAreRefusedNamingTheProblem) {
  auto f = hand_made().b;
  auto bad = f;
  bad[0] = std::byte{'T'};
  EXPECT_NE(error_of(bad).find("bad.bsdf: not a tensor file"), std::string::npos);
  bad = f;
  bad[12] = std::byte{2};
  EXPECT_NE(error_of(bad).find("version 2.0"), std::string::npos);
  bad = f;
  bad[18 + 2 + 1 + 2] = std::byte{12};  // field a's type
  EXPECT_NE(error_of(bad).find("type 12"), std::string::npos);
  bad = f;
  bad.resize(83);  // bc's data cut
  EXPECT_NE(error_of(bad).find("'bc'"), std::string::npos);
  EXPECT_NE(error_of(bad).find("past the end"), std::string::npos);
  bad = f;
  bad.resize(45);  // inside the field table
  EXPECT_NE(error_of(bad).find("truncated"), std::string::npos);
  Bytes twice;
  twice.str(std::string_view("tensor_file\0", 12)).put<std::uint8_t>(1).put<std::uint8_t>(0).put<std::uint32_t>(2);
  for (int i = 0; i < 2; ++i)
    twice.put<std::uint16_t>(1).str("a").put<std::uint16_t>(0).put<std::uint8_t>(1).put<std::uint64_t>(0);
  EXPECT_NE(error_of(twice.b).find("appears twice"), std::string::npos);
  Bytes overflow;
  overflow.str(std::string_view("tensor_file\0", 12)).put<std::uint8_t>(1).put<std::uint8_t>(0).put<std::uint32_t>(1);
  overflow.put<std::uint16_t>(1).str("a").put<std::uint16_t>(2).put<std::uint8_t>(11).put<std::uint64_t>(0);
  overflow.put<std::uint64_t>(1ull << 40).put<std::uint64_t>(1ull << 40);
  EXPECT_NE(error_of(overflow.b).find("overflow"), std::string::npos);
  Bytes many;
  many.str(std::string_view("tensor_file\0", 12))
      .put<std::uint8_t>(1)
      .put<std::uint8_t>(0)
      .put<std::uint32_t>(4000000000u);
  EXPECT_NE(error_of(many.b).find("4000000000 fields"), std::string::npos);
}

TEST(RglTensor, WriterRefusesInconsistentFields) {
  TensorFile t;
  const float v[] = {1, 2, 3};
  EXPECT_THROW(float32_field("x", {2}, v), UsageError);
  t.fields.push_back(float32_field("x", {3}, v));
  t.fields.push_back(float32_field("x", {3}, v));
  EXPECT_THROW(tensor_file_bytes(t), UsageError);
}

}  // namespace
}  // namespace specula::codec
