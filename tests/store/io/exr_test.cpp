// Tests of spectral OpenEXR input/output (store/io/exr.h), layout of Fichet et al. 2021.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/exr.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::write_file;

namespace fs = std::filesystem;
using specula::test::ScratchDir;

constexpr int kUint = 0, kHalf = 1, kFloat = 2;

// --- A minimal OpenEXR writer and reader written from the file-layout document (single-part scan-line
// files; the writer is uncompressed, the reader also undoes ZIP), so the library code is checked against an
// independent implementation of the format.

std::string le32(std::uint32_t v) {
  return {static_cast<char>(v), static_cast<char>(v >> 8), static_cast<char>(v >> 16), static_cast<char>(v >> 24)};
}
std::string le64(std::uint64_t v) {
  return le32(static_cast<std::uint32_t>(v)) + le32(static_cast<std::uint32_t>(v >> 32));
}
std::string lef(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return le32(u);
}
std::uint32_t rd32(const std::string& s, std::size_t at) {
  return static_cast<std::uint32_t>(static_cast<unsigned char>(s[at])) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 1])) << 8 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 2])) << 16 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 3])) << 24;
}

// Exact for the normal, representable values these tests use.
std::uint16_t to_half(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  if ((u & 0x7fffffffu) == 0) return static_cast<std::uint16_t>(u >> 16);
  const int exponent = static_cast<int>((u >> 23) & 0xff) - 127 + 15;
  EXPECT_TRUE(exponent > 0 && exponent < 31 && (u & 0x1fff) == 0) << f << " is not exact in half";
  return static_cast<std::uint16_t>(((u >> 16) & 0x8000) | (exponent << 10) | ((u >> 13) & 0x3ff));
}

float from_half(std::uint16_t h) {
  const int sign = h >> 15, exponent = (h >> 10) & 0x1f, mantissa = h & 0x3ff;
  float v;
  if (exponent == 0)
    v = std::ldexp(static_cast<float>(mantissa), -24);
  else if (exponent == 31)
    v = mantissa ? std::numeric_limits<float>::quiet_NaN() : std::numeric_limits<float>::infinity();
  else
    v = std::ldexp(static_cast<float>(mantissa + 1024), exponent - 25);
  return sign ? -v : v;
}

struct HandChannel {
  std::string name;
  int type = kFloat;
  std::vector<float> values;  // row-major over the data window
};

std::string attribute(const std::string& name, const std::string& type, const std::string& value) {
  return name + '\0' + type + '\0' + le32(static_cast<std::uint32_t>(value.size())) + value;
}

std::string make_exr(int xmin, int ymin, int width, int height, std::vector<HandChannel> channels,
                     const std::vector<std::pair<std::string, std::string>>& strings = {}) {
  std::sort(channels.begin(), channels.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::string chlist;
  for (const auto& c : channels) chlist += c.name + '\0' + le32(c.type) + std::string(4, '\0') + le32(1) + le32(1);
  chlist += '\0';
  const std::string box = le32(xmin) + le32(ymin) + le32(xmin + width - 1) + le32(ymin + height - 1);
  std::string header = std::string("\x76\x2f\x31\x01\x02\x00\x00\x00", 8);
  header += attribute("channels", "chlist", chlist);
  header += attribute("compression", "compression", std::string(1, '\0'));
  header += attribute("dataWindow", "box2i", box);
  header += attribute("displayWindow", "box2i", box);
  header += attribute("lineOrder", "lineOrder", std::string(1, '\0'));
  header += attribute("pixelAspectRatio", "float", lef(1.0f));
  header += attribute("screenWindowCenter", "v2f", lef(0.0f) + lef(0.0f));
  header += attribute("screenWindowWidth", "float", lef(1.0f));
  for (const auto& [name, value] : strings) header += attribute(name, "string", value);
  header += '\0';

  std::vector<std::string> lines;
  for (int y = 0; y < height; ++y) {
    std::string data;
    for (const auto& c : channels)
      for (int x = 0; x < width; ++x) {
        const float v = c.values[static_cast<std::size_t>(y * width + x)];
        if (c.type == kHalf) {
          const std::uint16_t h = to_half(v);
          data += static_cast<char>(h & 0xff);
          data += static_cast<char>(h >> 8);
        } else {
          data += lef(v);
        }
      }
    lines.push_back(le32(static_cast<std::uint32_t>(ymin + y)) + le32(static_cast<std::uint32_t>(data.size())) + data);
  }
  std::uint64_t offset = header.size() + 8 * lines.size();
  std::string table;
  for (const auto& l : lines) {
    table += le64(offset);
    offset += l.size();
  }
  std::string file = header + table;
  for (const auto& l : lines) file += l;
  return file;
}

struct ParsedExr {
  std::map<std::string, std::pair<std::string, std::string>> attributes;  // name -> (type, raw value)
  std::vector<std::pair<std::string, int>> channels;                      // in file order
  int xmin = 0, ymin = 0, width = 0, height = 0, compression = -1;
  std::map<std::string, std::vector<float>> pixels;  // row-major over the data window
};

ParsedExr parse_exr(const std::string& s) {
  ParsedExr p;
  EXPECT_EQ(rd32(s, 0), 20000630u) << "magic";
  EXPECT_EQ(rd32(s, 4) & 0xff, 2u);
  EXPECT_EQ(rd32(s, 4) & ~0xffu, 0u) << "expected a single-part scan-line file";
  std::size_t at = 8;
  while (s[at] != '\0') {
    const std::string name = s.c_str() + at;
    at += name.size() + 1;
    const std::string type = s.c_str() + at;
    at += type.size() + 1;
    const std::uint32_t size = rd32(s, at);
    at += 4;
    p.attributes[name] = {type, s.substr(at, size)};
    at += size;
  }
  ++at;
  const std::string& chlist = p.attributes.at("channels").second;
  for (std::size_t c = 0; chlist[c] != '\0';) {
    const std::string name = chlist.c_str() + c;
    c += name.size() + 1;
    p.channels.emplace_back(name, static_cast<int>(rd32(chlist, c)));
    c += 16;
  }
  const std::string& box = p.attributes.at("dataWindow").second;
  p.xmin = static_cast<int>(rd32(box, 0));
  p.ymin = static_cast<int>(rd32(box, 4));
  p.width = static_cast<int>(rd32(box, 8)) - p.xmin + 1;
  p.height = static_cast<int>(rd32(box, 12)) - p.ymin + 1;
  p.compression = static_cast<unsigned char>(p.attributes.at("compression").second[0]);
  EXPECT_TRUE(p.compression == 0 || p.compression == 3) << "reader handles NONE and ZIP only";
  const int lines_per_block = p.compression == 3 ? 16 : 1;
  const int blocks = (p.height + lines_per_block - 1) / lines_per_block;
  std::size_t bytes_per_line = 0;
  for (const auto& [name, type] : p.channels) {
    bytes_per_line += static_cast<std::size_t>(p.width) * (type == kHalf ? 2 : 4);
    p.pixels[name].resize(static_cast<std::size_t>(p.width) * p.height);
  }
  for (int b = 0; b < blocks; ++b) {
    const std::size_t chunk = rd32(s, at + 8 * b);
    const int y0 = static_cast<int>(rd32(s, chunk)) - p.ymin;
    const std::uint32_t size = rd32(s, chunk + 4);
    const int lines = std::min(lines_per_block, p.height - y0);
    std::string raw(bytes_per_line * lines, '\0');
    if (size == raw.size()) {
      raw = s.substr(chunk + 8, size);
    } else {
      std::string tmp(raw.size(), '\0');
      uLongf n = tmp.size();
      EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(tmp.data()), &n,
                           reinterpret_cast<const Bytef*>(s.data() + chunk + 8), size),
                Z_OK);
      for (std::size_t i = 1; i < tmp.size(); ++i) tmp[i] = static_cast<char>(tmp[i - 1] + tmp[i] - 128);
      const std::size_t half = (tmp.size() + 1) / 2;
      for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = i % 2 ? tmp[half + i / 2] : tmp[i / 2];
    }
    std::size_t pos = 0;
    for (int l = 0; l < lines; ++l)
      for (const auto& [name, type] : p.channels)
        for (int x = 0; x < p.width; ++x) {
          float v;
          if (type == kHalf) {
            v = from_half(static_cast<std::uint16_t>(static_cast<unsigned char>(raw[pos]) |
                                                     static_cast<unsigned char>(raw[pos + 1]) << 8));
            pos += 2;
          } else {
            const std::uint32_t u = rd32(raw, pos);
            std::memcpy(&v, &u, 4);
            pos += 4;
          }
          p.pixels[name][static_cast<std::size_t>((y0 + l) * p.width + x)] = v;
        }
  }
  return p;
}

Cube random_cube(std::size_t h, std::size_t w, std::vector<double> nm, const std::string& units, unsigned seed) {
  Cube c;
  c.resize(h, w, nm.size());
  c.wavelengths = WavelengthGrid(std::move(nm));
  c.units = units;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::uint32_t> bits;
  for (auto& v : c.data) {
    const std::uint32_t u = bits(rng);
    std::memcpy(&v, &u, 4);  // every float32 bit pattern: normals, subnormals, infinities, NaN payloads
  }
  return c;
}

bool bitwise_equal(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(ExrRoundTrip, ReflectiveIsBitwiseExact) {
  ScratchDir dir;
  const std::vector<double> nm{400, 412.3456789012345, 500.5, 600, 700.125};
  const Cube c = random_cube(37, 13, nm, "reflectance", 1);
  write_spectral_exr(dir / "r.exr", c);
  const Cube r = read_spectral_exr(dir / "r.exr");
  ASSERT_EQ(r.height, 37u);
  ASSERT_EQ(r.width, 13u);
  ASSERT_EQ(r.bands, 5u);
  EXPECT_TRUE(bitwise_equal(r.data, c.data));
  for (std::size_t b = 0; b < nm.size(); ++b) EXPECT_EQ(r.wavelengths[b], nm[b]) << b;
  EXPECT_EQ(r.units, "reflectance");
  EXPECT_EQ(r.provenance.importer, "exr");
  EXPECT_EQ(r.provenance.source_file, (dir / "r.exr").string());
  for (const auto& entry : fs::directory_iterator(dir.path()))
    EXPECT_EQ(entry.path().filename(), "r.exr") << "temporary left behind";

  // the file itself, decoded independently: FLOAT channels named in the layout, ZIP, version attribute
  const ParsedExr p = parse_exr(specula::test::read_bytes(dir / "r.exr"));
  EXPECT_EQ(p.compression, 3);
  std::vector<std::string> names;
  for (const auto& [name, type] : p.channels) {
    names.push_back(name);
    EXPECT_EQ(type, kFloat) << name;
  }
  EXPECT_EQ(names, (std::vector<std::string>{"T.400,000000nm", "T.412,3456789012345nm", "T.500,500000nm",
                                             "T.600,000000nm", "T.700,125000nm"}));
  EXPECT_EQ(p.attributes.at("spectralLayoutVersion"), (std::pair<std::string, std::string>{"string", "1.0"}));
  EXPECT_EQ(p.attributes.count("emissiveUnits"), 0u);
  std::vector<float> band2(c.height * c.width);
  for (std::size_t i = 0; i < band2.size(); ++i) band2[i] = c.data[i * 5 + 2];
  EXPECT_TRUE(bitwise_equal(p.pixels.at("T.500,500000nm"), band2));
}

TEST(ExrRoundTrip, EmissiveIsBitwiseExact) {
  ScratchDir dir;
  const Cube c = random_cube(20, 17, {380, 385, 390.5, 830}, "radiance", 2);
  write_spectral_exr(dir / "e.exr", c);
  const Cube r = read_spectral_exr(dir / "e.exr");
  ASSERT_EQ(r.bands, 4u);
  EXPECT_TRUE(bitwise_equal(r.data, c.data));
  EXPECT_TRUE(r.wavelengths.approx_equal(c.wavelengths, 0.0));
  EXPECT_EQ(r.units, "radiance");

  const ParsedExr p = parse_exr(specula::test::read_bytes(dir / "e.exr"));
  EXPECT_EQ(p.channels.front().first, "S0.380,000000nm");
  EXPECT_EQ(p.attributes.at("spectralLayoutVersion").second, "1.0");
  EXPECT_EQ(p.attributes.at("emissiveUnits"), (std::pair<std::string, std::string>{"string", "W.m^-2.sr^-1"}));
}

TEST(ExrWrite, RejectsInconsistentCubes) {
  ScratchDir dir;
  Cube c = random_cube(2, 2, {400, 500}, "reflectance", 3);
  c.data.pop_back();
  EXPECT_THROW(write_spectral_exr(dir / "x.exr", c), UsageError);
  Cube empty;
  EXPECT_THROW(write_spectral_exr(dir / "y.exr", empty), UsageError);
  EXPECT_FALSE(fs::exists(dir / "x.exr"));
}

TEST(ExrWrite, RgbHalfPreview) {
  ScratchDir dir;
  const std::size_t w = 5, h = 3;
  std::vector<float> rgb(3 * w * h);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i) * 0.25f - 2.0f;
  rgb[4] = 0.1f;
  write_exr_rgb(dir / "p.exr", w, h, rgb);
  const ParsedExr p = parse_exr(specula::test::read_bytes(dir / "p.exr"));
  ASSERT_EQ(p.channels.size(), 3u);
  for (const auto& [name, type] : p.channels) EXPECT_EQ(type, kHalf) << name;
  ASSERT_EQ(p.width, 5);
  ASSERT_EQ(p.height, 3);
  const char* names[3] = {"R", "G", "B"};
  for (std::size_t i = 0; i < w * h; ++i)
    for (int c = 0; c < 3; ++c) {
      const float expected = rgb[3 * i + c];
      EXPECT_NEAR(p.pixels.at(names[c])[i], expected, i * 3 + c == 4 ? 1e-4 : 0.0) << i << names[c];
    }
  EXPECT_THROW(write_exr_rgb(dir / "q.exr", w, h, std::vector<float>(3)), UsageError);
  EXPECT_THROW(read_spectral_exr(dir / "p.exr"), InputError);  // RGB only: no spectral channels
}

TEST(ExrRead, HandMadeReflectiveWithRgbAndOffsetDataWindow) {
  ScratchDir dir;
  const int w = 3, h = 2;
  auto ramp = [&](float base) {
    std::vector<float> v(w * h);
    for (int i = 0; i < w * h; ++i) v[i] = base + 0.25f * i;
    return v;
  };
  std::vector<HandChannel> channels{
      {"R", kHalf, ramp(10)},
      {"G", kHalf, ramp(20)},
      {"B", kHalf, ramp(30)},
      {"T.500nm", kFloat, ramp(0.5f)},
      {"T.400,5nm", kHalf, ramp(0.25f)},
      {"T.0.6um", kFloat, ramp(0.75f)},
      {"S0.450nm", kFloat, ramp(99)},
  };
  write_file(dir / "hand.exr", make_exr(-2, 3, w, h, channels, {{"spectralLayoutVersion", "1.0"}}));
  const Cube c = read_spectral_exr(dir / "hand.exr");
  ASSERT_EQ(c.width, 3u);
  ASSERT_EQ(c.height, 2u);
  ASSERT_EQ(c.bands, 3u);  // reflective wins over S0.*, R G B ignored
  EXPECT_EQ(c.units, "reflectance");
  EXPECT_EQ(c.wavelengths[0], 400.5);
  EXPECT_EQ(c.wavelengths[1], 500);
  EXPECT_NEAR(c.wavelengths[2], 600, 1e-9);
  for (std::size_t y = 0; y < 2; ++y)
    for (std::size_t x = 0; x < 3; ++x) {
      const float i = static_cast<float>(y * 3 + x) * 0.25f;
      EXPECT_EQ(c.pixel(y, x)[0], 0.25f + i);
      EXPECT_EQ(c.pixel(y, x)[1], 0.5f + i);
      EXPECT_EQ(c.pixel(y, x)[2], 0.75f + i);
    }
}

TEST(ExrRead, ChannelNameParsing) {
  ScratchDir dir;
  // Emissive channels in several spellings the layout allows, plus names that must be ignored.
  const std::vector<std::pair<std::string, double>> spectral{
      {"S0.380,5nm", 380.5},
      {"S0.0.4um", 400},
      {"S0.4.2e2nm", 420},
      {"S0.450.25nm", 450.25},
      {"S0.6e14Hz", 299792458.0 * 1e9 / 6e14},
      {"S0.5e-7m", 500},
      {"S0.0,51\xc2\xb5m", 510},
      {"S0.520000pm", 520},
  };
  const std::vector<std::string> ignored{"S1.500nm",  "M00.500nm", "T500nm", "S0.abcnm", "S0.500",
                                         "S0.500nmx", "S0.,nm",    "Y",      "S0.530xm"};
  std::vector<HandChannel> channels;
  for (std::size_t k = 0; k < spectral.size(); ++k)
    channels.push_back({spectral[k].first, kFloat, {static_cast<float>(k)}});
  for (const auto& name : ignored) channels.push_back({name, kFloat, {-1.0f}});
  write_file(dir / "names.exr", make_exr(0, 0, 1, 1, channels));
  const Cube c = read_spectral_exr(dir / "names.exr");
  ASSERT_EQ(c.bands, spectral.size());
  EXPECT_EQ(c.units, "radiance");
  auto sorted = spectral;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  for (std::size_t b = 0; b < c.bands; ++b) {
    EXPECT_NEAR(c.wavelengths[b], sorted[b].second, 1e-9) << sorted[b].first;
    const auto k = std::find(spectral.begin(), spectral.end(), sorted[b]) - spectral.begin();
    EXPECT_EQ(c.data[b], static_cast<float>(k)) << sorted[b].first;
  }
}

TEST(ExrRead, RejectsDuplicateWavelengthsAndNonSpectralFiles) {
  ScratchDir dir;
  write_file(dir / "dup.exr", make_exr(0, 0, 1, 1, {{"T.500nm", kFloat, {1}}, {"T.500,0nm", kFloat, {2}}}));
  std::string what = specula::test::input_error_text([&] { read_spectral_exr(dir / "dup.exr"); });
  EXPECT_NE(what.find("dup.exr"), std::string::npos) << what;
  EXPECT_NE(what.find("T.500nm"), std::string::npos) << what;

  write_file(dir / "rgb.exr", make_exr(0, 0, 1, 1, {{"R", kHalf, {1}}, {"G", kHalf, {1}}, {"B", kHalf, {1}}}));
  what = specula::test::input_error_text([&] { read_spectral_exr(dir / "rgb.exr"); });
  EXPECT_NE(what.find("rgb.exr"), std::string::npos) << what;
  EXPECT_NE(what.find("no spectral channels"), std::string::npos) << what;
}

TEST(ExrRead, TruncatedOrCorruptFileNamesTheFile) {
  ScratchDir dir;
  write_spectral_exr(dir / "full.exr", random_cube(64, 48, {400, 450, 500, 550, 600, 650}, "reflectance", 4));
  const std::string bytes = specula::test::read_bytes(dir / "full.exr");
  write_file(dir / "half.exr", bytes.substr(0, bytes.size() / 2));
  std::string what = specula::test::input_error_text([&] { read_spectral_exr(dir / "half.exr"); });
  EXPECT_NE(what.find((dir / "half.exr").string()), std::string::npos) << what;
  EXPECT_EQ(what.find('\n'), std::string::npos) << what;

  write_file(dir / "header.exr", bytes.substr(0, 200));
  EXPECT_NE(specula::test::input_error_text([&] { read_spectral_exr(dir / "header.exr"); }).find("header.exr"),
            std::string::npos);
  write_file(dir / "junk.exr", std::string(1000, 'x'));
  EXPECT_NE(specula::test::input_error_text([&] { read_spectral_exr(dir / "junk.exr"); }).find("junk.exr"),
            std::string::npos);
  EXPECT_THROW(read_spectral_exr(dir / "missing.exr"), InputError);
}

// --- Real data -----------------------------------------------------------------------------------------

// Reads the transposed reflectance CSV: first column wavelength_nm, then one quoted column per patch.
struct ReflectanceTable {
  std::vector<std::string> names;
  std::vector<double> nm;
  std::vector<std::vector<double>> values;  // values[row][patch]
};

ReflectanceTable read_reflectance_csv(const fs::path& path) {
  std::ifstream in(path);
  ReflectanceTable t;
  std::string line;
  std::getline(in, line);
  std::stringstream header(line);
  std::string cell;
  std::getline(header, cell, ',');
  while (std::getline(header, cell, ',')) {
    cell.erase(std::remove(cell.begin(), cell.end(), '"'), cell.end());
    t.names.push_back(cell);
  }
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::stringstream row(line);
    std::getline(row, cell, ',');
    t.nm.push_back(std::stod(cell));
    t.values.emplace_back();
    while (std::getline(row, cell, ',')) t.values.back().push_back(std::stod(cell));
  }
  return t;
}

TEST(ExrRealData, MacbethChartMatchesOhtaReflectances) {
  SPECULA_REQUIRE_SHARED();
  const fs::path data = specula::test::shared_dir() / "data";
  const Cube c = read_spectral_exr(data / "images/Macbeth.exr");
  ASSERT_EQ(c.width, 600u);
  ASSERT_EQ(c.height, 400u);
  ASSERT_EQ(c.bands, 36u);
  EXPECT_EQ(c.units, "reflectance");
  EXPECT_TRUE(c.wavelengths.uniform());
  EXPECT_EQ(c.wavelengths.front(), 380);
  EXPECT_EQ(c.wavelengths.back(), 730);

  const ReflectanceTable ohta = read_reflectance_csv(data / "reflectance/colorchecker24_ohta1997_reflectance.csv");
  ASSERT_EQ(ohta.names.size(), 24u);
  std::vector<std::size_t> row_of_band(c.bands);
  for (std::size_t b = 0; b < c.bands; ++b) {
    const auto it = std::find(ohta.nm.begin(), ohta.nm.end(), c.wavelengths[b]);
    ASSERT_NE(it, ohta.nm.end()) << c.wavelengths[b];
    row_of_band[b] = static_cast<std::size_t>(it - ohta.nm.begin());
  }

  // Patch geometry, read off an sRGB rendering of the file and its band sums: a black background with a
  // 6 x 4 grid of 100 x 100 px cells; in each cell the patch covers x in [100c + 11, 100c + 95] and y in
  // [100r + 11, 100r + 95]. Centres are therefore at ((c + 0.535) / 6, (r + 0.535) / 4) of the image size,
  // and a window of +-20 px (0.2 of a cell) stays well inside every patch. The uniformity check below fails
  // if a window ever reaches the black border.
  const double cell_w = c.width / 6.0, cell_h = c.height / 4.0;
  const long half = std::lround(0.2 * cell_w);
  // Macbeth.exr holds measured spectra of a chart, not Ohta's table, so they differ. Measured per patch over the
  // whole common range 380-730 nm: RMS 0.0017 (black) to 0.0665 (foliage), max |difference| 0.003 to 0.228
  // (foliage at 730 nm). The large values all sit in the red tail above 680 nm, where dark skin, foliage,
  // blue flower and purplish blue rise much less in the file than in Ohta's data (chart batches differ most
  // there). Over 400-670 nm the agreement is tighter: RMS at most 0.025 and max at most 0.080 (blue flower).
  // Tolerances are about 1.2-1.4x the worst measured values; over 400-670 nm every patch must also be closer
  // to its own Ohta spectrum than to any other, which fails for a mislocated window or a wrong band order.
  const double full_rms_tolerance = 0.085, full_max_tolerance = 0.27;
  const double core_rms_tolerance = 0.035, core_max_tolerance = 0.10;
  auto in_core = [&](std::size_t b) { return c.wavelengths[b] >= 400 && c.wavelengths[b] <= 670; };
  double worst_rms = 0, worst_max = 0;
  for (std::size_t patch = 0; patch < 24; ++patch) {
    const std::size_t col = patch % 6, row = patch / 6;
    const long cx = std::lround((col + 0.535) * cell_w), cy = std::lround((row + 0.535) * cell_h);
    std::vector<double> mean(c.bands, 0.0), lo(c.bands, 1e9), hi(c.bands, -1e9);
    std::size_t n = 0;
    for (long y = cy - half; y <= cy + half; ++y)
      for (long x = cx - half; x <= cx + half; ++x, ++n)
        for (std::size_t b = 0; b < c.bands; ++b) {
          const double v = c.pixel(static_cast<std::size_t>(y), static_cast<std::size_t>(x))[b];
          mean[b] += v;
          lo[b] = std::min(lo[b], v);
          hi[b] = std::max(hi[b], v);
        }
    double sum_sq = 0, max_abs = 0, core_sum_sq = 0, core_max_abs = 0;
    std::size_t core_n = 0;
    for (std::size_t b = 0; b < c.bands; ++b) {
      mean[b] /= static_cast<double>(n);
      EXPECT_LT(hi[b] - lo[b], 0.01) << "window of patch " << patch << " is not uniform";
      const double d = mean[b] - ohta.values[row_of_band[b]][patch];
      sum_sq += d * d;
      max_abs = std::max(max_abs, std::abs(d));
      if (in_core(b)) {
        core_sum_sq += d * d;
        core_max_abs = std::max(core_max_abs, std::abs(d));
        ++core_n;
      }
    }
    const double rms = std::sqrt(sum_sq / static_cast<double>(c.bands));
    const double core_rms = std::sqrt(core_sum_sq / static_cast<double>(core_n));
    worst_rms = std::max(worst_rms, rms);
    worst_max = std::max(worst_max, max_abs);
    std::cout << "  patch " << patch + 1 << " (" << ohta.names[patch] << "): 380-730 nm RMS " << rms << " max "
              << max_abs << "; 400-670 nm RMS " << core_rms << " max " << core_max_abs << "\n";
    EXPECT_LT(rms, full_rms_tolerance) << ohta.names[patch];
    EXPECT_LT(max_abs, full_max_tolerance) << ohta.names[patch];
    EXPECT_LT(core_rms, core_rms_tolerance) << ohta.names[patch];
    EXPECT_LT(core_max_abs, core_max_tolerance) << ohta.names[patch];

    std::size_t best = 0;
    double best_d = 1e300;
    for (std::size_t other = 0; other < 24; ++other) {
      double d2 = 0;
      for (std::size_t b = 0; b < c.bands; ++b)
        if (in_core(b)) d2 += std::pow(mean[b] - ohta.values[row_of_band[b]][other], 2);
      if (d2 < best_d) {
        best_d = d2;
        best = other;
      }
    }
    EXPECT_EQ(best, patch) << ohta.names[patch] << " looks like " << ohta.names[best];
  }
  std::cout << "  worst RMS " << worst_rms << ", worst max " << worst_max << "\n";
}

TEST(ExrRealData, D65IsEmissiveAndMatchesCieTable) {
  SPECULA_REQUIRE_SHARED();
  const fs::path data = specula::test::shared_dir() / "data";
  const Cube c = read_spectral_exr(data / "images/D65.exr");
  ASSERT_EQ(c.width, 1u);
  ASSERT_EQ(c.height, 1u);
  EXPECT_EQ(c.units, "radiance");
  ASSERT_GT(c.bands, 50u);

  std::ifstream in(data / "cie/cie_illuminant_D65_spd.csv");
  std::map<double, double> cie;
  std::string line;
  while (std::getline(in, line)) {
    double nm = 0, v = 0;
    if (std::sscanf(line.c_str(), "%lf,%lf", &nm, &v) == 2) cie[nm] = v;
  }
  ASSERT_FALSE(cie.empty());
  std::size_t compared = 0;
  for (std::size_t b = 0; b < c.bands; ++b) {
    const auto it = cie.find(c.wavelengths[b]);
    if (it == cie.end()) continue;
    EXPECT_NEAR(c.data[b], it->second, 1e-3 * it->second) << c.wavelengths[b];
    ++compared;
  }
  EXPECT_GE(compared, 50u);
}

}  // namespace
}  // namespace specula::store

TEST(ExrMask, MaskTravelsAsAlphaChannel) {
  specula::test::ScratchDir dir;
  specula::store::Cube c;
  c.resize(3, 5, 4);
  for (std::size_t i = 0; i < c.data.size(); ++i) c.data[i] = float(i);
  c.wavelengths = specula::WavelengthGrid({450, 500, 550, 600});
  c.units = "reflectance";
  c.mask.assign(15, 1);
  c.mask[4] = c.mask[11] = 0;
  specula::store::write_spectral_exr(dir / "m.exr", c);
  auto back = specula::store::read_spectral_exr(dir / "m.exr");
  EXPECT_EQ(back.mask, c.mask);
  EXPECT_EQ(back.data, c.data);
  c.mask.clear();
  specula::store::write_spectral_exr(dir / "n.exr", c);
  EXPECT_TRUE(specula::store::read_spectral_exr(dir / "n.exr").mask.empty());
}
