#include "specula/store/io/mask.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"
#include "test_support.h"

namespace specula::store {
namespace {

// An ENVI byte image: `bands` bands of width x height bytes (BSQ) and its header.
void write_envi_bytes(const std::filesystem::path& data, std::size_t w, std::size_t h, std::size_t bands,
                      const std::vector<std::uint8_t>& bytes, const std::string& extra = "") {
  std::filesystem::path hdr = data;
  hdr.replace_extension(".hdr");
  std::ofstream(hdr)
      << "ENVI\nsamples = " << w << "\nlines = " << h << "\nbands = " << bands
      << "\nheader offset = 0\nfile type = ENVI Standard\ndata type = 1\ninterleave = bsq\nbyte order = 0\n"
      << extra;
  std::ofstream(data, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

TEST(Mask, EnviByteImageFromItsHeaderOrDataFile) {
  const test::ScratchDir dir;
  const std::vector<std::uint8_t> bytes{0, 1, 255, 0, 7, 1};
  write_envi_bytes(dir / "roi.img", 3, 2, 1, bytes);
  for (const char* name : {"roi.hdr", "roi.img"}) {
    const Mask m = read_mask(dir / name);
    EXPECT_EQ(m.width, 3u);
    EXPECT_EQ(m.height, 2u);
    EXPECT_EQ(m.valid, (std::vector<std::uint8_t>{0, 1, 1, 0, 1, 1})) << name;
  }
  // ENVI's data ignore value marks invalid pixels too.
  write_envi_bytes(dir / "ign.img", 3, 2, 1, bytes, "data ignore value = 7\n");
  EXPECT_EQ(read_mask(dir / "ign.img").valid, (std::vector<std::uint8_t>{0, 1, 1, 0, 0, 1}));
}

TEST(Mask, PngFirstChannel) {
  const test::ScratchDir dir;
  // Red channel decides: pixel 1 is red 0 (invalid) though green and blue are not.
  write_png_rgb8(dir / "m.png", 2, 1, std::vector<std::uint8_t>{9, 0, 0, 0, 200, 200});
  const Mask m = read_mask(dir / "m.png");
  EXPECT_EQ(m.valid, (std::vector<std::uint8_t>{1, 0}));
  std::filesystem::copy_file(dir / "m.png", dir / "m.mask");  // recognised by its signature, whatever the name
  EXPECT_EQ(read_mask(dir / "m.mask").valid, m.valid);
}

TEST(Mask, PngBesideASameStemEnviHeaderIsReadAsThePng) {
  const test::ScratchDir dir;
  // m.hdr describes a 4 x 3 one-band byte image (m.img); m.png is a 2 x 1 PNG. Asked for m.png, the PNG is read.
  write_envi_bytes(dir / "m.img", 4, 3, 1, std::vector<std::uint8_t>(12, 0));
  write_png_rgb8(dir / "m.png", 2, 1, std::vector<std::uint8_t>{0, 5, 5, 3, 0, 0});
  const Mask m = read_mask(dir / "m.png");
  EXPECT_EQ(m.width, 2u);
  EXPECT_EQ(m.height, 1u);
  EXPECT_EQ(m.valid, (std::vector<std::uint8_t>{0, 1}));
  // The ENVI mask beside it is still what its header and data file name.
  for (const char* name : {"m.hdr", "m.img"}) {
    const Mask e = read_mask(dir / name);
    EXPECT_EQ(e.width, 4u) << name;
    EXPECT_EQ(e.valid, std::vector<std::uint8_t>(12, 0)) << name;
  }
  // A PNG under another name beside a same-stem header is known by its signature.
  std::filesystem::copy_file(dir / "m.png", dir / "q.mask");
  write_envi_bytes(dir / "q.img", 4, 3, 1, std::vector<std::uint8_t>(12, 1));
  EXPECT_EQ(read_mask(dir / "q.mask").valid, m.valid);
}

TEST(Mask, WhatIsNotAMaskIsOneLineNamingTheFile) {
  const test::ScratchDir dir;
  write_envi_bytes(dir / "rgb.img", 2, 1, 3, std::vector<std::uint8_t>(6, 1));
  EXPECT_NE(test::input_error_text([&] {
              read_mask(dir / "rgb.img");
            }).find("rgb.hdr: a mask has one band, this ENVI image has 3"),
            std::string::npos);
  std::ofstream(dir / "junk.bin") << "not an image";
  const std::string junk = test::input_error_text([&] { read_mask(dir / "junk.bin"); });
  EXPECT_NE(junk.find("junk.bin: a mask is a PNG or a one-band ENVI image"), std::string::npos) << junk;
  std::ofstream(dir / "cut.png") << "\x89PNG\r\n\x1a\n"
                                 << "truncated";
  EXPECT_NE(test::input_error_text([&] { read_mask(dir / "cut.png"); }).find("cut.png"), std::string::npos);
  EXPECT_NE(test::input_error_text([&] { read_mask(dir / "none.png"); }).find("none.png: mask file not found"),
            std::string::npos);
  write_envi_bytes(dir / "short.img", 4, 4, 1, std::vector<std::uint8_t>(5, 1));
  EXPECT_NE(test::input_error_text([&] { read_mask(dir / "short.hdr"); }).find("short"), std::string::npos);
}

}  // namespace
}  // namespace specula::store
