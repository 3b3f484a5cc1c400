#include "specula/store/io/envi.h"

#include <bit>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::error_of;
using specula::test::write_file;

using test::ScratchDir;

// The hand-built 2 x 3 x 4 image: lines 2, samples 3, bands 4.
constexpr std::size_t kH = 2, kW = 3, kB = 4;
double value_at(std::size_t y, std::size_t x, std::size_t b) { return 100.0 * y + 10.0 * x + b + 1; }

// Appends `v` as an ENVI sample of `data_type`, most significant byte first when big_endian.
void append_sample(std::string& out, double v, int data_type, bool big_endian) {
  std::uint64_t bits = 0;
  std::size_t n = 0;
  switch (data_type) {
    case 1:
      bits = static_cast<std::uint8_t>(v);
      n = 1;
      break;
    case 2:
      bits = static_cast<std::uint16_t>(static_cast<std::int16_t>(v));
      n = 2;
      break;
    case 12:
      bits = static_cast<std::uint16_t>(v);
      n = 2;
      break;
    case 3:
      bits = static_cast<std::uint32_t>(static_cast<std::int32_t>(v));
      n = 4;
      break;
    case 4:
      bits = std::bit_cast<std::uint32_t>(static_cast<float>(v));
      n = 4;
      break;
    case 5:
      bits = std::bit_cast<std::uint64_t>(v);
      n = 8;
      break;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t shift = 8 * (big_endian ? n - 1 - i : i);
    out += static_cast<char>((bits >> shift) & 0xff);
  }
}

std::string interleaved(const char* il, int data_type, bool big_endian, double offset = 0) {
  std::string out;
  const std::string s = il;
  if (s == "bsq") {
    for (std::size_t b = 0; b < kB; ++b)
      for (std::size_t y = 0; y < kH; ++y)
        for (std::size_t x = 0; x < kW; ++x) append_sample(out, value_at(y, x, b) + offset, data_type, big_endian);
  } else if (s == "bil") {
    for (std::size_t y = 0; y < kH; ++y)
      for (std::size_t b = 0; b < kB; ++b)
        for (std::size_t x = 0; x < kW; ++x) append_sample(out, value_at(y, x, b) + offset, data_type, big_endian);
  } else {
    for (std::size_t y = 0; y < kH; ++y)
      for (std::size_t x = 0; x < kW; ++x)
        for (std::size_t b = 0; b < kB; ++b) append_sample(out, value_at(y, x, b) + offset, data_type, big_endian);
  }
  return out;
}

std::string header(const std::string& interleave, int data_type, int byte_order, const std::string& extra = {}) {
  return "ENVI\nsamples = 3\nlines = 2\nbands = 4\nheader offset = 0\ndata type = " + std::to_string(data_type) +
         "\ninterleave = " + interleave + "\nbyte order = " + std::to_string(byte_order) +
         "\nwavelength units = Nanometers\nwavelength = {400, 500, 600, 700}\n" + extra;
}

void expect_known_cube(const Cube& c, double offset = 0) {
  ASSERT_EQ(c.height, kH);
  ASSERT_EQ(c.width, kW);
  ASSERT_EQ(c.bands, kB);
  ASSERT_EQ(c.data.size(), kH * kW * kB);
  for (std::size_t y = 0; y < kH; ++y)
    for (std::size_t x = 0; x < kW; ++x)
      for (std::size_t b = 0; b < kB; ++b)
        EXPECT_EQ(c.data[(y * kW + x) * kB + b], static_cast<float>(value_at(y, x, b) + offset))
            << "y=" << y << " x=" << x << " b=" << b;
}

TEST(Envi, LiteralBsqBytesGiveKnownPixels) {
  ScratchDir dir;
  // bsq uint8: band 0 rows (1,11,21) (101,111,121), band 1 ..., written out literally.
  const std::string bytes = {1, 11, 21, 101, 111, 121, 2, 12, 22, 102, 112, 122,
                             3, 13, 23, 103, 113, 123, 4, 14, 24, 104, 114, 124};
  write_file(dir / "lit.raw", bytes);
  write_file(dir / "lit.hdr", header("bsq", 1, 0));
  const Cube c = read_envi(dir / "lit.hdr");
  EXPECT_EQ(c.pixel(0, 0)[0], 1.0f);
  EXPECT_EQ(c.pixel(1, 2)[3], 124.0f);
  EXPECT_EQ(c.pixel(0, 1)[2], 13.0f);
  EXPECT_EQ(c.pixel(1, 0)[1], 102.0f);
  expect_known_cube(c);
  EXPECT_TRUE(c.mask.empty());
  EXPECT_EQ(c.provenance.importer, "envi");
}

TEST(Envi, LiteralBilBytesGiveKnownPixels) {
  ScratchDir dir;
  // bil uint8: line 0 holds band 0 (1,11,21), band 1 (2,12,22), ...; then line 1.
  const std::string bytes = {1,   11,  21,  2,   12,  22,  3,   13,  23,  4,   14,  24,
                             101, 111, 121, 102, 112, 122, 103, 113, 123, 104, 114, 124};
  write_file(dir / "lit.raw", bytes);
  write_file(dir / "lit.hdr", header("bil", 1, 0));
  expect_known_cube(read_envi(dir / "lit.hdr"));
}

TEST(Envi, EveryInterleaveTypeAndByteOrder) {
  for (const char* il : {"bsq", "bil", "bip"})
    for (int dt : {1, 2, 3, 4, 5, 12})
      for (int order : {0, 1}) {
        SCOPED_TRACE(std::string(il) + " type " + std::to_string(dt) + " order " + std::to_string(order));
        ScratchDir dir;
        // Signed types get negative values to check sign handling; float types get a fraction.
        const double offset = (dt == 2 || dt == 3) ? -150.0 : (dt == 4 || dt == 5) ? 0.25 : 0.0;
        write_file(dir / "img.bin", interleaved(il, dt, order == 1, offset));
        write_file(dir / "img.bin.hdr", header(il, dt, order));
        expect_known_cube(read_envi(dir / "img.bin"), offset);
      }
}

TEST(Envi, RoundTripEveryInterleaveWithMaskFwhmUnits) {
  Cube c;
  c.resize(3, 5, 4);
  for (std::size_t i = 0; i < c.data.size(); ++i) c.data[i] = 0.001f * static_cast<float>(i) - 0.3f;
  c.mask.assign(15, 1);
  c.mask[7] = 0;
  c.wavelengths = WavelengthGrid({410.5, 500, 600.25, 690});
  c.fwhm = {10, 12.5, 9, 11};
  c.units = "reflectance";
  for (Interleave il : {Interleave::bsq, Interleave::bil, Interleave::bip}) {
    SCOPED_TRACE(static_cast<int>(il));
    ScratchDir dir;
    write_envi(dir / "rt.raw", c, il);
    ASSERT_TRUE(std::filesystem::exists(dir / "rt.hdr"));
    const Cube r = read_envi(dir / "rt.raw");
    ASSERT_EQ(r.height, 3u);
    ASSERT_EQ(r.width, 5u);
    ASSERT_EQ(r.bands, 4u);
    ASSERT_EQ(r.mask, c.mask);
    for (std::size_t y = 0; y < 3; ++y)
      for (std::size_t x = 0; x < 5; ++x)
        if (c.valid(y, x)) {
          for (std::size_t b = 0; b < 4; ++b) EXPECT_EQ(r.pixel(y, x)[b], c.pixel(y, x)[b]);
        }
    EXPECT_TRUE(r.wavelengths.approx_equal(c.wavelengths, 0));
    EXPECT_EQ(r.fwhm, c.fwhm);
    EXPECT_EQ(r.units, "reflectance");
  }
}

// Larger than one 2 MiB block of rows, so block boundaries are crossed on read and write.
TEST(Envi, LargeImageMatchesHandBuiltBytesInEveryInterleave) {
  constexpr std::size_t H = 200, W = 64, B = 100;
  const auto v = [](std::size_t y, std::size_t x, std::size_t b) { return static_cast<float>((y * W + x) * B + b); };
  Cube c;
  c.resize(H, W, B);
  for (std::size_t y = 0; y < H; ++y)
    for (std::size_t x = 0; x < W; ++x)
      for (std::size_t b = 0; b < B; ++b) c.data[(y * W + x) * B + b] = v(y, x, b);
  c.wavelengths = WavelengthGrid::range(400, 400 + 3 * (B - 1), 3);
  for (const char* il : {"bsq", "bil", "bip"}) {
    SCOPED_TRACE(il);
    const std::string s = il;
    std::string expected;
    expected.reserve(H * W * B * 4);
    if (s == "bsq") {
      for (std::size_t b = 0; b < B; ++b)
        for (std::size_t y = 0; y < H; ++y)
          for (std::size_t x = 0; x < W; ++x) append_sample(expected, v(y, x, b), 4, false);
    } else if (s == "bil") {
      for (std::size_t y = 0; y < H; ++y)
        for (std::size_t b = 0; b < B; ++b)
          for (std::size_t x = 0; x < W; ++x) append_sample(expected, v(y, x, b), 4, false);
    } else {
      for (std::size_t y = 0; y < H; ++y)
        for (std::size_t x = 0; x < W; ++x)
          for (std::size_t b = 0; b < B; ++b) append_sample(expected, v(y, x, b), 4, false);
    }
    ScratchDir dir;
    const Interleave mode = s == "bsq" ? Interleave::bsq : s == "bil" ? Interleave::bil : Interleave::bip;
    write_envi(dir / "big.raw", c, mode);
    EXPECT_TRUE(test::read_bytes(dir / "big.raw") == expected);
    write_file(dir / "hand.raw", expected);
    std::string wl;
    for (std::size_t b = 0; b < B; ++b) wl += (b ? "," : "") + std::to_string(400 + 3 * b);
    write_file(dir / "hand.hdr", "ENVI\nsamples = 64\nlines = 200\nbands = 100\ndata type = 4\ninterleave = " + s +
                                     "\nwavelength units = nm\nwavelength = {" + wl + "}\n");
    const Cube r = read_envi(dir / "hand.raw");
    EXPECT_TRUE(r.data == c.data);
    EXPECT_TRUE(r.wavelengths.approx_equal(c.wavelengths, 1e-9));
  }
}

TEST(Envi, WrittenBytesAreLittleEndianFloatInFileOrder) {
  Cube c;
  c.resize(1, 2, 2);
  c.data = {1.0f, 2.0f, 3.0f, -0.5f};  // pixel 0: (1, 2), pixel 1: (3, -0.5)
  c.mask = {1, 0};
  c.wavelengths = WavelengthGrid({500, 600});
  ScratchDir dir;
  write_envi(dir / "b.raw", c, Interleave::bsq);
  // bsq: band 0 = (1, masked), band 1 = (2, masked); -9999 = 0xC61C3C00, 1 = 0x3F800000, 2 = 0x40000000.
  const std::string expected = {0, 0, '\x80', '\x3f', 0, '\x3c', '\x1c', '\xc6',
                                0, 0, 0,      '\x40', 0, '\x3c', '\x1c', '\xc6'};
  EXPECT_EQ(test::read_bytes(dir / "b.raw"), expected);
  const std::string hdr = test::read_bytes(dir / "b.hdr");
  EXPECT_TRUE(hdr.starts_with("ENVI\n"));
  EXPECT_NE(hdr.find("wavelength units = Nanometers"), std::string::npos) << hdr;
  EXPECT_NE(hdr.find("data ignore value = -9999"), std::string::npos) << hdr;
  EXPECT_NE(hdr.find("data type = 4"), std::string::npos) << hdr;
  EXPECT_NE(hdr.find("byte order = 0"), std::string::npos) << hdr;
  const EnviHeader h = parse_envi_header(hdr, "b.hdr");
  EXPECT_EQ(h.wavelength, (std::vector<double>{500, 600}));
  EXPECT_EQ(h.interleave, Interleave::bsq);
}

TEST(Envi, ParseHeaderKeysCaseInsensitiveAndMultilineBraces) {
  const std::string text =
      "ENVI\r\n"
      "Description = {A scene\r\n  over two lines}\r\n"
      "SAMPLES = 640\r\n"
      "Lines   =  480\r\n"
      "bands = 3\r\n"
      "Data  Type = 12\r\n"
      "INTERLEAVE = BIL\r\n"
      "; a comment\r\n"
      "wavelength = {\r\n 450.5,\r\n 550,\r\n 650 }\r\n"
      "fwhm = {5, 6, 7}\r\n"
      "band names = {red, green,\n blue}\r\n"
      "data ignore value = -1.5\r\n";
  const EnviHeader h = parse_envi_header(text, "x.hdr");
  EXPECT_EQ(h.samples, 640u);
  EXPECT_EQ(h.lines, 480u);
  EXPECT_EQ(h.bands, 3u);
  EXPECT_EQ(h.data_type, 12);
  EXPECT_EQ(h.interleave, Interleave::bil);
  EXPECT_EQ(h.byte_order, 0);
  EXPECT_EQ(h.header_offset, 0u);
  EXPECT_EQ(h.wavelength, (std::vector<double>{450.5, 550, 650}));
  EXPECT_EQ(h.fwhm, (std::vector<double>{5, 6, 7}));
  EXPECT_EQ(h.band_names, (std::vector<std::string>{"red", "green", "blue"}));
  ASSERT_TRUE(h.data_ignore_value.has_value());
  EXPECT_EQ(*h.data_ignore_value, -1.5);
  EXPECT_EQ(h.description, "A scene\n  over two lines");
  EXPECT_TRUE(h.wavelength_units.empty());
}

TEST(Envi, MicrometresConvertedToNanometres) {
  for (const char* units : {"Micrometers", "um", "micrometers"}) {
    SCOPED_TRACE(units);
    ScratchDir dir;
    write_file(dir / "u.raw", interleaved("bip", 4, false));
    write_file(dir / "u.hdr",
               "ENVI\nsamples = 3\nlines = 2\nbands = 4\ndata type = 4\ninterleave = bip\nwavelength units = " +
                   std::string(units) + "\nwavelength = {0.4, 0.45, 0.5125, 2.5}\nfwhm = {0.01, 0.01, 0.02, 0.02}\n");
    const Cube c = read_envi(dir / "u.hdr");
    ASSERT_EQ(c.wavelengths.size(), 4u);
    EXPECT_NEAR(c.wavelengths[0], 400.0, 1e-9);
    EXPECT_NEAR(c.wavelengths[1], 450.0, 1e-9);
    EXPECT_NEAR(c.wavelengths[2], 512.5, 1e-9);
    EXPECT_NEAR(c.wavelengths[3], 2500.0, 1e-9);
    ASSERT_EQ(c.fwhm.size(), 4u);
    EXPECT_NEAR(c.fwhm[0], 10.0, 1e-9);
    EXPECT_NEAR(c.fwhm[3], 20.0, 1e-9);
    expect_known_cube(c);
  }
}

TEST(Envi, IgnoreValueMasksPixels) {
  ScratchDir dir;
  // uint16 bip, 1 line x 3 samples x 2 bands: pixel 0 = (7, 8), pixel 1 = (0, 0), pixel 2 = (5, 0).
  const std::string bytes = {7, 0, 8, 0, 0, 0, 0, 0, 5, 0, 0, 0};
  write_file(dir / "m.raw", bytes);
  write_file(dir / "m.hdr",
             "ENVI\nsamples = 3\nlines = 1\nbands = 2\ndata type = 12\ninterleave = bip\nbyte order = 0\n"
             "data ignore value = 0\nwavelength = {500, 600}\nspecula units = counts\n");
  const Cube c = read_envi(dir / "m.raw");
  EXPECT_EQ(c.mask, (std::vector<std::uint8_t>{1, 0, 0}));
  EXPECT_EQ(c.pixel(0, 0)[1], 8.0f);
  EXPECT_EQ(c.units, "counts");
}

TEST(Envi, HeaderOffsetSkipsLeadingBytes) {
  ScratchDir dir;
  write_file(dir / "o.dat", std::string(37, '\x55') + interleaved("bil", 2, true));
  write_file(dir / "o.hdr", header("bil", 2, 1, "header offset = 37\n"));
  const Cube c = read_envi(dir / "o.hdr");
  expect_known_cube(c);
  EXPECT_EQ(c.units, "unknown");
}

TEST(Envi, MissingWavelengthsNeedFallback) {
  ScratchDir dir;
  write_file(dir / "n.raw", interleaved("bsq", 1, false));
  write_file(dir / "n.hdr", "ENVI\nsamples = 3\nlines = 2\nbands = 4\ndata type = 1\ninterleave = bsq\n");
  const std::string msg = error_of([&] { read_envi(dir / "n.hdr"); });
  EXPECT_NE(msg.find("`wavelengths` option"), std::string::npos) << msg;
  EXPECT_NE(msg.find("n.hdr"), std::string::npos) << msg;
  const Cube c = read_envi(dir / "n.hdr", WavelengthGrid::range(400, 700, 100));
  EXPECT_EQ(c.wavelengths.size(), 4u);
  EXPECT_EQ(c.wavelengths[3], 700.0);
  expect_known_cube(c);
  const std::string wrong = error_of([&] { read_envi(dir / "n.hdr", WavelengthGrid::range(400, 700, 10)); });
  EXPECT_NE(wrong.find("4 bands"), std::string::npos) << wrong;
}

TEST(Envi, TruncatedAndOversizedDataNameBothSizes) {
  ScratchDir dir;
  write_file(dir / "t.raw", interleaved("bsq", 2, false).substr(0, 40));
  write_file(dir / "t.hdr", header("bsq", 2, 0));
  const std::string msg = error_of([&] { read_envi(dir / "t.hdr"); });
  EXPECT_NE(msg.find("t.hdr: data file t.raw has 40 bytes, header needs 48 "
                     "(samples 3 x lines 2 x bands 4 x 2 bytes + offset 0)"),
            std::string::npos)
      << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos);
  write_file(dir / "t.raw", interleaved("bsq", 2, false) + "xx");
  const std::string big = error_of([&] { read_envi(dir / "t.hdr"); });
  EXPECT_NE(big.find("has 50 bytes, header needs 48"), std::string::npos) << big;
}

// ENVI allows an unsorted wavelength list: the bands are sorted by wavelength with their values, fwhm and bbl,
// and the irregular grid is kept exactly (no resampling). A wavelength listed twice is an error naming it.
TEST(Envi, UnsortedWavelengthsSortTheBandsWithTheirValues) {
  ScratchDir dir;
  const std::string wl = "wavelength units = Nanometers\nwavelength = {650, 400, 523.5, 410}\nfwhm = {6, 3, 5, 4}\n";
  std::string text = header("bil", 4, 0) + wl;  // the later wavelength list replaces header()'s
  write_file(dir / "u.hdr", text);
  write_file(dir / "u.raw", interleaved("bil", 4, false));
  const Cube c = read_envi(dir / "u.hdr");
  ASSERT_EQ(c.bands, kB);
  EXPECT_EQ(std::vector<double>(c.wavelengths.values().begin(), c.wavelengths.values().end()),
            (std::vector<double>{400, 410, 523.5, 650}));
  EXPECT_EQ(c.fwhm, (std::vector<double>{3, 4, 5, 6}));
  const std::size_t file_band[kB] = {1, 3, 2, 0};
  for (std::size_t y = 0; y < kH; ++y)
    for (std::size_t x = 0; x < kW; ++x)
      for (std::size_t k = 0; k < kB; ++k)
        EXPECT_EQ(c.data[(y * kW + x) * kB + k], static_cast<float>(value_at(y, x, file_band[k])));

  write_file(dir / "u.hdr", text + "bbl = {1, 1, 0, 1}\n");  // band 3 (523.5 nm) bad
  const Cube kept = read_envi(dir / "u.hdr");
  ASSERT_EQ(kept.bands, 3u);
  EXPECT_EQ(kept.wavelengths[2], 650.0);
  EXPECT_EQ(kept.data[2], static_cast<float>(value_at(0, 0, 0)));

  write_file(dir / "u.hdr", header("bil", 4, 0) + "wavelength = {650, 400, 650, 410}\n");
  const std::string m = error_of([&] { read_envi(dir / "u.hdr"); });
  EXPECT_NE(m.find("u.hdr: wavelength 650 appears twice (bands 1 and 3); remove one of them"), std::string::npos) << m;
}

TEST(Envi, BadHeadersAreInputErrors) {
  const std::string ok = header("bsq", 4, 0);
  const auto msg = [](const std::string& text) { return error_of([&] { parse_envi_header(text, "bad.hdr"); }); };
  const auto expect_has = [](const std::string& m, const std::string& part) {
    EXPECT_NE(m.find(part), std::string::npos) << m;
    EXPECT_TRUE(m.starts_with("bad.hdr")) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  };
  EXPECT_NO_THROW(parse_envi_header(ok, "ok.hdr"));
  expect_has(msg(header("bsq", 7, 0)), "data type = 7 is not supported");
  expect_has(msg("ENVI\nsamples = 3\nlines = 2\nbands = 4\ndata type = 4\n"), "'interleave' is missing");
  expect_has(msg("ENVI\nlines = 2\nbands = 4\ndata type = 4\ninterleave = bsq\n"), "'samples' is missing");
  expect_has(msg("ENVI\nsamples = 3\nlines = 2\nbands = 4\ninterleave = bsq\n"), "'data type' is missing");
  expect_has(msg("ENVI\nsamples = 3\nlines = 2\nbands = 3\ndata type = 4\ninterleave = bsq\nwavelength = {400, 500}\n"),
             "wavelength has 2 values but bands = 3");
  expect_has(msg("hello\x01world\nsamples = 3\n"), "not an ENVI header");
  expect_has(msg(""), "not an ENVI header");
  expect_has(msg("ENVI\nthis line is junk\n"), "line 2: expected \"key = value\"");
  expect_has(msg("ENVI\nsamples = 12abc\n"), "samples = 12abc is not a whole number");
  expect_has(msg("ENVI\nsamples = -3\n"), "is not a whole number");
  expect_has(msg("ENVI\nsamples = 0\nlines = 2\nbands = 4\n"), "must be at least 1");
  expect_has(msg("ENVI\nsamples = 99999999999999999999999\n"), "out of range");
  expect_has(msg("ENVI\nsamples = 4294967296\nlines = 4294967296\nbands = 1\ndata type = 1\ninterleave = bsq\n"),
             "1 TiB");
  expect_has(msg("ENVI\nsamples = 1000000\nlines = 1000000\nbands = 1000\ndata type = 4\ninterleave = bsq\n"), "1 TiB");
  expect_has(msg(ok + "wavelength = {400, 500,\n600, 700\n"), "never closed");
  expect_has(msg(ok + "fwhm = {1, nan, 3, 4}\n"), "fwhm value 2 \"nan\" is not a finite number");
  expect_has(msg(ok + "byte order = 2\n"), "byte order = 2 must be 0");
  expect_has(msg(ok + "interleave = bsx\n"), "interleave = bsx is not one of bsq, bil, bip");
  expect_has(msg(ok + "data ignore value = abc\n"), "data ignore value = abc is not a finite number");
  expect_has(msg(ok + "= 5\n"), "has no key");
}

TEST(Envi, UnitsAndPathsProblems) {
  ScratchDir dir;
  write_file(dir / "w.raw", interleaved("bsq", 4, false));
  write_file(dir / "w.hdr",
             "ENVI\nsamples = 3\nlines = 2\nbands = 4\ndata type = 4\ninterleave = bsq\n"
             "wavelength units = GHz\nwavelength = {1, 2, 3, 4}\n");
  EXPECT_NE(error_of([&] { read_envi(dir / "w.hdr"); }).find("wavelength units = GHz is not supported"),
            std::string::npos);
  EXPECT_EQ(read_envi(dir / "w.hdr", WavelengthGrid({450, 500, 550, 600})).wavelengths[3], 600.0);
  write_file(dir / "w.hdr",
             "ENVI\nsamples = 3\nlines = 2\nbands = 4\ndata type = 4\ninterleave = bsq\n"
             "wavelength = {0.4, 0.5, 0.6, 0.7}\n");
  EXPECT_NE(error_of([&] { read_envi(dir / "w.hdr"); }).find("wavelength units = Micrometers"), std::string::npos);
  EXPECT_NE(error_of([&] { read_envi(dir / "missing.hdr"); }).find("no such file"), std::string::npos);
  write_file(dir / "lonely.hdr", header("bsq", 4, 0));
  EXPECT_NE(error_of([&] { read_envi(dir / "lonely.hdr"); }).find("no data file beside the header"), std::string::npos);
  write_file(dir / "nohdr.raw", "abc");
  EXPECT_NE(error_of([&] { read_envi(dir / "nohdr.raw"); }).find("no ENVI header beside it"), std::string::npos);
}

TEST(Envi, WriteRejectsMisuse) {
  Cube c;
  c.resize(2, 2, 2);
  c.data.pop_back();
  ScratchDir dir;
  EXPECT_THROW(write_envi(dir / "x.raw", c), UsageError);
  c.resize(2, 2, 2);
  EXPECT_THROW(write_envi(dir / "x.hdr", c), UsageError);
  c.mask = {1, 0};
  EXPECT_THROW(write_envi(dir / "x.raw", c), UsageError);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.raw"));
}

}  // namespace
}  // namespace specula::store
