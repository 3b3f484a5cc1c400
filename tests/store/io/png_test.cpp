// Tests of PNG input/output and PNG band stacks (store/io/png_stack.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::write_file;

namespace fs = std::filesystem;
using specula::test::ScratchDir;

// A minimal PNG encoder written from the specification (zlib "stored" blocks, no compression), so the reader
// is checked against files our writer did not make.
std::uint32_t crc32(const std::string& bytes) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xffffffffu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xff] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

std::string be32(std::uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}

std::string chunk(const std::string& type, const std::string& data) {
  return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc32(type + data));
}

std::string zlib_stored(const std::string& raw) {
  std::string out = "\x78\x01";
  std::size_t pos = 0;
  do {
    const std::size_t n = std::min<std::size_t>(65535, raw.size() - pos);
    const bool last = pos + n == raw.size();
    out += static_cast<char>(last ? 1 : 0);
    out += static_cast<char>(n & 0xff);
    out += static_cast<char>(n >> 8);
    out += static_cast<char>(~n & 0xff);
    out += static_cast<char>((~n >> 8) & 0xff);
    out += raw.substr(pos, n);
    pos += n;
  } while (pos < raw.size());
  std::uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  return out + be32((b << 16) | a);
}

// `scanlines` holds each row's filter byte (0) followed by the packed samples.
std::string make_png(std::uint32_t width, std::uint32_t height, int bit_depth, int color_type,
                     const std::string& scanlines, const std::string& extra_chunks = "") {
  std::string ihdr = be32(width) + be32(height);
  ihdr += static_cast<char>(bit_depth);
  ihdr += static_cast<char>(color_type);
  ihdr += std::string(3, '\0');
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + extra_chunks +
         chunk("IDAT", zlib_stored(scanlines)) + chunk("IEND", "");
}

std::string gray16_scanlines(std::size_t width, const std::vector<std::uint16_t>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i % width == 0) s += '\0';
    s += static_cast<char>(v[i] >> 8);
    s += static_cast<char>(v[i] & 0xff);
  }
  return s;
}

std::string gray8_scanlines(std::size_t width, const std::vector<std::uint8_t>& v, int copies = 1) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i % width == 0) s += '\0';
    s += std::string(copies, static_cast<char>(v[i]));
  }
  return s;
}

TEST(PngRead, HandMade16BitGrayIsBigEndianOnDisk) {
  ScratchDir dir;
  const std::vector<std::uint16_t> values{0, 1, 256, 0x1234, 0xfffe, 0xffff};
  write_file(dir / "g16.png", make_png(3, 2, 16, 0, gray16_scanlines(3, values)));
  const PngImage img = read_png(dir / "g16.png");
  EXPECT_EQ(img.width, 3u);
  EXPECT_EQ(img.height, 2u);
  EXPECT_EQ(img.channels, 1u);
  EXPECT_EQ(img.bit_depth, 16);
  EXPECT_EQ(img.samples, values);
}

TEST(PngRead, HandMadePaletteWithTransparencyExpandsToRgba) {
  ScratchDir dir;
  // 2-bit palette indices, 3 x 2 pixels: row 0 = 0 1 2, row 1 = 2 2 1 (packed high bits first).
  const std::string plte(
      "\x10\x20\x30"
      "\xff\x00\x80"
      "\x05\x06\x07",
      9);
  const std::string trns("\x00\x7f", 2);  // entry 2 has no alpha entry, so it is opaque
  const std::string rows =
      std::string("\x00", 1) + static_cast<char>(0b00011000) + std::string("\x00", 1) + static_cast<char>(0b10100100);
  write_file(dir / "pal.png", make_png(3, 2, 2, 3, rows, chunk("PLTE", plte) + chunk("tRNS", trns)));
  const PngImage img = read_png(dir / "pal.png");
  EXPECT_EQ(img.channels, 4u);
  EXPECT_EQ(img.bit_depth, 8);
  const std::vector<std::uint16_t> expected{0x10, 0x20, 0x30, 0x00, 0xff, 0x00, 0x80, 0x7f, 0x05, 0x06, 0x07, 0xff,
                                            0x05, 0x06, 0x07, 0xff, 0x05, 0x06, 0x07, 0xff, 0xff, 0x00, 0x80, 0x7f};
  EXPECT_EQ(img.samples, expected);
}

TEST(PngRead, HandMadeOneBitGrayWidensToFullScale) {
  ScratchDir dir;
  const std::string rows = std::string("\x00", 1) + static_cast<char>(0b10100000);
  write_file(dir / "bw.png", make_png(4, 1, 1, 0, rows));
  const PngImage img = read_png(dir / "bw.png");
  EXPECT_EQ(img.bit_depth, 8);
  EXPECT_EQ(img.samples, (std::vector<std::uint16_t>{255, 0, 255, 0}));
}

TEST(PngRoundTrip, Rgb8) {
  ScratchDir dir;
  const std::size_t w = 37, h = 23;
  std::mt19937 rng(11);
  std::vector<std::uint8_t> rgb(3 * w * h);
  for (auto& v : rgb) v = static_cast<std::uint8_t>(rng());
  write_png_rgb8(dir / "rgb.png", w, h, rgb);
  const PngImage img = read_png(dir / "rgb.png");
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  ASSERT_EQ(img.channels, 3u);
  EXPECT_EQ(img.bit_depth, 8);
  EXPECT_TRUE(std::equal(rgb.begin(), rgb.end(), img.samples.begin(), img.samples.end()));
  for (const auto& entry : fs::directory_iterator(dir.path()))
    EXPECT_EQ(entry.path().filename(), "rgb.png") << "temporary left behind";
}

TEST(PngRoundTrip, Rgb8InMemory) {
  ScratchDir dir;
  const std::size_t w = 41, h = 17;
  std::mt19937 rng(12);
  std::vector<std::uint8_t> rgb(3 * w * h);
  for (auto& v : rgb) v = static_cast<std::uint8_t>(rng());
  const std::vector<std::uint8_t> bytes = encode_png_rgb8(w, h, rgb);
  std::ofstream(dir / "m.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  const PngImage img = read_png(dir / "m.png");
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  ASSERT_EQ(img.channels, 3u);
  EXPECT_TRUE(std::equal(rgb.begin(), rgb.end(), img.samples.begin(), img.samples.end()));
  EXPECT_THROW(encode_png_rgb8(w, h, std::span<const std::uint8_t>(rgb).first(10)), UsageError);
}

TEST(PngRoundTrip, Gray16) {
  ScratchDir dir;
  const std::size_t w = 19, h = 31;
  std::mt19937 rng(12);
  std::vector<std::uint16_t> v(w * h);
  for (auto& s : v) s = static_cast<std::uint16_t>(rng());
  v[0] = 0;
  v[1] = 0xffff;
  v[2] = 0x00ff;
  v[3] = 0xff00;
  write_png_gray16(dir / "g.png", w, h, v);
  const PngImage img = read_png(dir / "g.png");
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  EXPECT_EQ(img.channels, 1u);
  EXPECT_EQ(img.bit_depth, 16);
  EXPECT_EQ(img.samples, v);
}

TEST(PngWrite, RejectsWrongSampleCount) {
  ScratchDir dir;
  std::vector<std::uint8_t> rgb(3 * 4 * 4 - 1);
  EXPECT_THROW(write_png_rgb8(dir / "x.png", 4, 4, rgb), UsageError);
  std::vector<std::uint16_t> g(4);
  EXPECT_THROW(write_png_gray16(dir / "y.png", 0, 4, g), UsageError);
  EXPECT_FALSE(fs::exists(dir / "x.png"));
}

TEST(PngRead, TruncatedFileNamesTheFile) {
  ScratchDir dir;
  const std::size_t w = 64, h = 64;
  std::mt19937 rng(3);
  std::vector<std::uint8_t> rgb(3 * w * h);
  for (auto& v : rgb) v = static_cast<std::uint8_t>(rng());
  write_png_rgb8(dir / "full.png", w, h, rgb);
  const std::string bytes = specula::test::read_bytes(dir / "full.png");
  ASSERT_GT(bytes.size(), 3 * w * h / 2);
  write_file(dir / "half.png", bytes.substr(0, bytes.size() / 2));
  const std::string what = specula::test::input_error_text([&] { read_png(dir / "half.png"); });
  EXPECT_NE(what.find((dir / "half.png").string()), std::string::npos) << what;
  EXPECT_NE(what.find("truncated"), std::string::npos) << what;
  EXPECT_EQ(what.find('\n'), std::string::npos);
  // cut just before IEND: the pixels are complete but the file is not
  write_file(dir / "noend.png", bytes.substr(0, bytes.size() - 12));
  EXPECT_THROW(read_png(dir / "noend.png"), InputError);
}

TEST(PngRead, CorruptHeaderAndSignature) {
  ScratchDir dir;
  std::string png = make_png(3, 2, 16, 0, gray16_scanlines(3, {1, 2, 3, 4, 5, 6}));
  std::string bad_crc = png;
  bad_crc[8 + 8 + 3] = 9;  // width byte inside IHDR, so the chunk CRC no longer matches
  write_file(dir / "crc.png", bad_crc);
  std::string what = specula::test::input_error_text([&] { read_png(dir / "crc.png"); });
  EXPECT_NE(what.find((dir / "crc.png").string()), std::string::npos) << what;
  EXPECT_NE(what.find("CRC"), std::string::npos) << what;

  std::string bad_sig = png;
  bad_sig[1] = 'Q';
  write_file(dir / "sig.png", bad_sig);
  what = specula::test::input_error_text([&] { read_png(dir / "sig.png"); });
  EXPECT_NE(what.find((dir / "sig.png").string()), std::string::npos) << what;

  // a valid header claiming 100000 x 100000 pixels in a tiny file is rejected before any allocation
  std::string huge = make_png(100000, 100000, 16, 0, gray16_scanlines(3, {1, 2, 3}));
  write_file(dir / "huge.png", huge);
  what = specula::test::input_error_text([&] { read_png(dir / "huge.png"); });
  EXPECT_NE(what.find("huge.png"), std::string::npos) << what;

  write_file(dir / "empty.png", "");
  EXPECT_THROW(read_png(dir / "empty.png"), InputError);
  EXPECT_THROW(read_png(dir / "missing.png"), InputError);
}

TEST(PngStack, HandMadeThreeBandDirectory) {
  ScratchDir dir;
  const std::size_t w = 3, h = 2;
  // band 1: 16-bit gray; band 2: 8-bit gray; band 3: 8-bit RGB with R = G = B (as in some CAVE scenes)
  const std::vector<std::uint16_t> b1{0, 65535, 1000, 2000, 3000, 32768};
  const std::vector<std::uint8_t> b2{0, 255, 10, 20, 30, 128};
  const std::vector<std::uint8_t> b3{7, 8, 9, 250, 251, 252};
  fs::create_directory(dir / "scene_ms");
  write_file(dir / "scene_ms/scene_ms_01.png", make_png(w, h, 16, 0, gray16_scanlines(w, b1)));
  write_file(dir / "scene_ms/scene_ms_02.png", make_png(w, h, 8, 0, gray8_scanlines(w, b2)));
  write_file(dir / "scene_ms/scene_ms_03.png", make_png(w, h, 8, 2, gray8_scanlines(w, b3, 3)));
  write_file(dir / "scene_ms/scene_RGB.bmp", "not a png");

  const Cube c = read_png_stack({dir / "scene_ms"}, WavelengthGrid({450, 550, 650}));
  ASSERT_EQ(c.height, h);
  ASSERT_EQ(c.width, w);
  ASSERT_EQ(c.bands, 3u);
  EXPECT_EQ(c.wavelengths[2], 650);
  EXPECT_EQ(c.provenance.importer, "png-stack");
  for (std::size_t p = 0; p < w * h; ++p) {
    EXPECT_FLOAT_EQ(c.data[p * 3 + 0], static_cast<float>(b1[p] / 65535.0)) << p;
    EXPECT_FLOAT_EQ(c.data[p * 3 + 1], static_cast<float>(b2[p] / 255.0)) << p;
    EXPECT_FLOAT_EQ(c.data[p * 3 + 2], static_cast<float>(b3[p] / 255.0)) << p;
  }
  EXPECT_EQ(c.pixel(0, 1)[0], 1.0f);
  EXPECT_EQ(c.pixel(0, 1)[1], 1.0f);

  // an explicit list keeps the caller's order
  const Cube r =
      read_png_stack({dir / "scene_ms/scene_ms_03.png", dir / "scene_ms/scene_ms_01.png"}, WavelengthGrid({500, 600}));
  EXPECT_FLOAT_EQ(r.pixel(1, 2)[0], static_cast<float>(252 / 255.0));
  EXPECT_FLOAT_EQ(r.pixel(1, 2)[1], static_cast<float>(32768 / 65535.0));
}

TEST(PngStack, DirectoryOrderComparesNumbersByValue) {
  ScratchDir dir;
  for (int k : {10, 2, 1}) {
    const std::vector<std::uint8_t> v{static_cast<std::uint8_t>(k)};
    write_file(dir / ("band_" + std::to_string(k) + ".png"), make_png(1, 1, 8, 0, gray8_scanlines(1, v)));
  }
  const Cube c = read_png_stack({dir.path()}, WavelengthGrid({400, 500, 600}));
  EXPECT_FLOAT_EQ(c.data[0] * 255, 1);
  EXPECT_FLOAT_EQ(c.data[1] * 255, 2);
  EXPECT_FLOAT_EQ(c.data[2] * 255, 10);
}

TEST(PngStack, CountMismatchTellsToPassWavelengths) {
  ScratchDir dir;
  for (int k = 1; k <= 3; ++k)
    write_png_gray16(dir / ("s_0" + std::to_string(k) + ".png"), 2, 2, std::vector<std::uint16_t>(4, 9));
  const std::string what = specula::test::input_error_text([&] {
    read_png_stack({dir.path()}, WavelengthGrid({400, 500}));
  });
  EXPECT_NE(what.find("3 PNG files"), std::string::npos) << what;
  EXPECT_NE(what.find("2 wavelengths"), std::string::npos) << what;
  EXPECT_NE(what.find("`wavelengths` option"), std::string::npos) << what;
  EXPECT_NE(specula::test::input_error_text([&] {
              read_png_stack({dir.path()}, WavelengthGrid());
            }).find("`wavelengths` option"),
            std::string::npos);

  fs::create_directory(dir / "empty");
  EXPECT_THROW(read_png_stack({dir / "empty"}, WavelengthGrid({400})), InputError);
}

TEST(PngStack, RejectsColourBandsSizeMismatchAndCorruptBands) {
  ScratchDir dir;
  write_png_gray16(dir / "a.png", 2, 2, std::vector<std::uint16_t>(4, 1));
  std::vector<std::uint8_t> rgb(12, 50);
  rgb[3 * 3 + 1] = 51;  // pixel (1, 1): G differs from R
  write_png_rgb8(dir / "colour.png", 2, 2, rgb);
  std::string what = specula::test::input_error_text([&] {
    read_png_stack({dir / "a.png", dir / "colour.png"}, WavelengthGrid({400, 500}));
  });
  EXPECT_NE(what.find("colour.png"), std::string::npos) << what;
  EXPECT_NE(what.find("(1, 1)"), std::string::npos) << what;

  write_png_gray16(dir / "big.png", 3, 2, std::vector<std::uint16_t>(6, 1));
  what = specula::test::input_error_text([&] {
    read_png_stack({dir / "a.png", dir / "big.png"}, WavelengthGrid({400, 500}));
  });
  EXPECT_NE(what.find("big.png"), std::string::npos) << what;

  const std::string bytes = specula::test::read_bytes(dir / "big.png");
  write_file(dir / "cut.png", bytes.substr(0, bytes.size() / 2));
  what = specula::test::input_error_text([&] {
    read_png_stack({dir / "a.png", dir / "cut.png"}, WavelengthGrid({400, 500}));
  });
  EXPECT_NE(what.find("cut.png"), std::string::npos) << what;
}

}  // namespace
}  // namespace specula::store
