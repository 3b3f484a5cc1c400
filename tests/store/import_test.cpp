#include "specula/store/import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::store {
namespace {

// A float32 BIP ENVI image whose value at (y, x, b) is y + 10 x + 100 b, on 500, 510, ... nm.
void write_envi(const std::filesystem::path& base, std::size_t h, std::size_t w, std::size_t b, float nan_at = -1) {
  std::vector<float> v(h * w * b);
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x)
      for (std::size_t k = 0; k < b; ++k) v[(y * w + x) * b + k] = float(y + 10 * x + 100 * k);
  if (nan_at >= 0) v[std::size_t(nan_at)] = std::nanf("");
  std::string wl;
  for (std::size_t k = 0; k < b; ++k) wl += (k ? ", " : "") + std::to_string(500 + 10 * k);
  std::ofstream(base.string() + ".hdr") << "ENVI\nsamples = " << w << "\nlines = " << h << "\nbands = " << b
                                        << "\nheader offset = 0\ndata type = 4\ninterleave = bip\nbyte order = 0\n"
                                        << "wavelength units = Nanometers\nwavelength = {" << wl << "}\n";
  std::ofstream(base.string() + ".raw", std::ios::binary)
      .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
}

TEST(Import, FilesLandAsTheirObjectsResampledWhenAsked) {
  const test::ScratchDir dir;
  write_envi(dir / "scene", 2, 3, 3);
  std::ofstream(dir / "lib.csv") << "name,500,510,520\nchip,0.1,0.2,0.3\n";
  ImportOptions o;
  o.wavelengths = WavelengthGrid::range(505, 515, 5);  // resampled: 505 nm is halfway between bands 0 and 1
  StoreWriter w(dir / "db.h5", {});
  const ImportReport r = import_files(w, {dir / "scene.hdr", dir / "lib.csv"}, o);
  w.commit();
  ASSERT_EQ(r.imported.size(), 2u);
  EXPECT_EQ(r.imported[0].rfind("imported image scene: 2x3", 0), 0u) << r.imported[0];
  const Store s = Store::open(dir / "db.h5");
  const Cube c = s.read_image("scene");
  ASSERT_EQ(c.bands, 3u);
  // Pixel (1, 2): y + 10 x + 100 b at b = 0.5, 1, 1.5.
  EXPECT_NEAR(c.data[(1 * 3 + 2) * 3 + 0], 21 + 50, 1e-4);
  EXPECT_NEAR(c.data[(1 * 3 + 2) * 3 + 2], 21 + 150, 1e-4);
  const Collection lib = s.read_collection("lib");
  EXPECT_NEAR(lib.values[1], 0.2, 1e-6);
}

// Issue 18: an unsorted, non-uniform band list is kept exactly, sorted with its values, never resampled.
TEST(Import, AnUnsortedIrregularBandListIsKeptExactlyWithItsValues) {
  const test::ScratchDir dir;
  const std::vector<float> v = {1, 2, 3, 4, 5, 6, 7, 8};  // 1 x 2 pixels x 4 bands, BIP
  std::ofstream(dir / "u.hdr") << "ENVI\nsamples = 2\nlines = 1\nbands = 4\nheader offset = 0\ndata type = 4\n"
                               << "interleave = bip\nbyte order = 0\nwavelength units = Nanometers\n"
                               << "wavelength = {700, 403, 455.5, 410}\n";
  std::ofstream(dir / "u.raw", std::ios::binary).write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
  StoreWriter w(dir / "db.h5", {});
  import_files(w, {dir / "u.hdr"}, {});
  w.commit();
  const Cube c = Store::open(dir / "db.h5").read_image("u");
  EXPECT_EQ(std::vector<double>(c.wavelengths.values().begin(), c.wavelengths.values().end()),
            (std::vector<double>{403, 410, 455.5, 700}));
  EXPECT_EQ(c.data, (std::vector<float>{2, 4, 3, 1, 6, 8, 7, 5}));
}

TEST(Import, NanIsRejectedOrMaskedWithANote) {
  const test::ScratchDir dir;
  write_envi(dir / "nan", 2, 2, 3, /*nan_at=*/4);  // pixel 1, band 1
  StoreWriter w(dir / "db.h5", {});
  EXPECT_NE(test::input_error_text([&] { import_files(w, {dir / "nan.hdr"}, {}); }).find("set the `nan` option to \"mask\" to keep the image"),
            std::string::npos);
  ImportOptions o;
  o.nan = NanPolicy::mask;
  const ImportReport r = import_files(w, {dir / "nan.hdr"}, o);
  w.commit();
  ASSERT_EQ(r.notes.size(), 1u);
  EXPECT_NE(r.notes[0].find("masked 1 pixels holding NaN/Inf"), std::string::npos) << r.notes[0];
  EXPECT_EQ(Store::open(dir / "db.h5").read_image("nan").mask, (std::vector<std::uint8_t>{1, 0, 1, 1}));
}

TEST(Import, MisuseNamesTheOption) {
  const test::ScratchDir dir;
  write_envi(dir / "a", 1, 1, 2);
  write_envi(dir / "b", 1, 1, 2);
  StoreWriter w(dir / "db.h5", {});
  ImportOptions o;
  o.name = "one";
  try {
    import_files(w, {dir / "a.hdr", dir / "b.hdr"}, o);
    ADD_FAILURE();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("the `name` option names one object but the inputs make 2"), std::string::npos)
        << e.what();
  }
  try {
    detect_import_format(dir / "scene.xyz");
    ADD_FAILURE();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("scene.xyz: cannot tell the format"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("--"), std::string::npos) << e.what();
  }
  EXPECT_EQ(detect_import_format(dir / "a.hdr"), "envi");
  EXPECT_EQ(detect_import_format(dir / "x.MAT"), "mat");
}

}  // namespace
}  // namespace specula::store
