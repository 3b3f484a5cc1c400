// GeoTIFFs written by GDAL's own Python bindings (the peer), read back through store/io/gdal.h and imported by
// row strips: values planted at (row, column, band), wavelengths from each place GDAL keeps them, nodata masked.
#include "specula/store/io/gdal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/import.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula::store {
namespace {

using test::error_of;
using test::ScratchDir;

bool have_gdal_python() {
  return std::system("OPENBLAS_CORETYPE=SkylakeX /usr/bin/python3 -c 'from osgeo import gdal' >/dev/null 2>&1") == 0;
}

#define REQUIRE_GDAL_PYTHON() \
  if (!have_gdal_python()) GTEST_SKIP() << "Debian's python3-gdal is not installed (scripts/setup-deps installs it)"

// Runs a Python snippet that has gdal, numpy and `out` (the path) defined; fails the test if it fails.
void python(const std::filesystem::path& out, const std::string& body) {
  const std::filesystem::path script = out.string() + ".py";
  std::ofstream(script) << "from osgeo import gdal\nimport numpy as np\nout = '" << out.string() << "'\n" << body;
  ASSERT_EQ(std::system(("OPENBLAS_CORETYPE=SkylakeX /usr/bin/python3 '" + script.string() + "'").c_str()), 0) << body;
}

double value_at(std::size_t y, std::size_t x, std::size_t b) { return y + 10.0 * x + 1000.0 * b; }

// An H x W x B float32 GeoTIFF with value_at(y, x, b), nodata -9999 at (1, 2) in band 1, and `band_setup` run on
// each band `bd` (index b).
void write_tiff(const std::filesystem::path& out, int h, int w, int nb, const std::string& band_setup,
                const std::string& options = "[]") {
  python(out, "d = gdal.GetDriverByName('GTiff').Create(out, " + std::to_string(w) + ", " + std::to_string(h) + ", " +
                  std::to_string(nb) + ", gdal.GDT_Float32, options=" + options +
                  ")\n"
                  "y, x = np.mgrid[0:" +
                  std::to_string(h) + ", 0:" + std::to_string(w) +
                  "]\n"
                  "for b in range(" +
                  std::to_string(nb) +
                  "):\n"
                  "    bd = d.GetRasterBand(b + 1)\n"
                  "    a = (y + 10.0 * x + 1000.0 * b).astype(np.float32)\n"
                  "    if b == 1: a[1, 2] = -9999\n"
                  "    bd.WriteArray(a)\n"
                  "    bd.SetNoDataValue(-9999)\n"
                  "    " +
                  band_setup +
                  "\n"
                  "d = None\n");
}

TEST(Gdal, ReadsRowStripsWithEnviWavelengthsAndNodata) {
  REQUIRE_GDAL_PYTHON();
  const ScratchDir dir;
  write_tiff(
      dir / "a.tif", 7, 5, 3,
      "bd.SetMetadataItem('wavelength', str(0.45 + 0.05 * b)); bd.SetMetadataItem('wavelength_units', 'Micrometers')");
  GdalRaster r(dir / "a.tif", {});
  ASSERT_EQ(r.height(), 7u);
  ASSERT_EQ(r.width(), 5u);
  ASSERT_EQ(r.bands(), 3u);
  EXPECT_NEAR(r.wavelengths()[0], 450, 1e-9);
  EXPECT_NEAR(r.wavelengths()[2], 550, 1e-9);
  EXPECT_EQ(r.driver(), "GTiff");
  std::vector<float> s(3 * 5 * 3);
  std::vector<std::uint8_t> m(3 * 5);
  r.read_rows(1, 3, s, m);  // rows 1..3
  for (std::size_t y = 0; y < 3; ++y)
    for (std::size_t x = 0; x < 5; ++x) {
      const bool planted = y == 0 && x == 2;
      EXPECT_EQ(m[y * 5 + x], planted ? 0 : 1) << y << "," << x;
      for (std::size_t b = 0; b < 3; ++b)
        if (!(planted && b == 1)) {
          EXPECT_EQ(s[(y * 5 + x) * 3 + b], value_at(y + 1, x, b));
        }
    }
}

TEST(Gdal, WavelengthsFromDescriptionsOrTheCallerElseOneLineAskingForThem) {
  REQUIRE_GDAL_PYTHON();
  const ScratchDir dir;
  write_tiff(dir / "desc.tif", 3, 3, 3, "bd.SetDescription('Band %d (%.1f nm)' % (b + 1, 400 + 10 * b))");
  EXPECT_NEAR(GdalRaster(dir / "desc.tif", {}).wavelengths()[2], 420, 1e-9);
  write_tiff(dir / "um.tif", 3, 3, 2, "bd.SetMetadataItem('CENTRAL_WAVELENGTH_UM', str(0.5 + 0.1 * b), 'IMAGERY')");
  EXPECT_NEAR(GdalRaster(dir / "um.tif", {}).wavelengths()[1], 600, 1e-9);
  write_tiff(dir / "none.tif", 3, 3, 3, "pass");
  const std::string e = error_of([&] { GdalRaster(dir / "none.tif", {}); });
  EXPECT_NE(e.find("none.tif: the GTiff raster's 3 bands carry no wavelengths"), std::string::npos) << e;
  EXPECT_NE(e.find("give the `wavelengths` option"), std::string::npos) << e;
  EXPECT_NEAR(GdalRaster(dir / "none.tif", WavelengthGrid::range(500, 520, 10)).wavelengths()[1], 510, 1e-9);
  const std::string wrong = error_of([&] { GdalRaster(dir / "none.tif", WavelengthGrid::range(500, 510, 10)); });
  EXPECT_NE(wrong.find("gives 2 wavelengths for 3 bands"), std::string::npos) << wrong;
}

TEST(Gdal, TruncatedOrForeignFilesAreOneLineNamingTheFile) {
  REQUIRE_GDAL_PYTHON();
  const ScratchDir dir;
  write_tiff(dir / "full.tif", 64, 64, 4, "pass", "['TILED=YES', 'BLOCKXSIZE=16', 'BLOCKYSIZE=16']");
  const auto size = std::filesystem::file_size(dir / "full.tif");
  std::filesystem::copy_file(dir / "full.tif", dir / "cut.tif");
  std::filesystem::resize_file(dir / "cut.tif", size / 2);
  const std::string e = error_of([&] {
    GdalRaster r(dir / "cut.tif", WavelengthGrid::range(500, 530, 10));
    std::vector<float> s(64 * 64 * 4);
    std::vector<std::uint8_t> m(64 * 64);
    r.read_rows(0, 64, s, m);
  });
  EXPECT_EQ(e.rfind((dir / "cut.tif").string() + ": ", 0), 0u) << e;
  EXPECT_NE(e.find("GDAL: "), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  test::write_file(dir / "text.tif", "not a tiff at all");
  const std::string f = error_of([&] { GdalRaster(dir / "text.tif", {}); });
  EXPECT_NE(f.find("text.tif: not a raster GDAL can read (GDAL: "), std::string::npos) << f;
}

TEST(Gdal, ImportStreamsStripsThatMatchTheFileAndLeavesTheStoreOnBadData) {
  REQUIRE_GDAL_PYTHON();
  const ScratchDir dir;
  write_tiff(dir / "big.tif", 37, 11, 4, "bd.SetMetadataItem('wavelength', str(500 + 10 * b))");
  ImportOptions o;
  o.strip_bytes = 11 * (4 * 4 + 1) * 2;  // 2 rows per strip: many strips, the last one short
  {
    StoreWriter w(dir / "db.h5", {});
    const ImportReport r = import_files(w, {dir / "big.tif"}, o);
    w.commit();
    ASSERT_EQ(r.imported.size(), 1u);
    EXPECT_EQ(r.imported[0], "imported image big: 37x11, 4 bands 500-530 nm step 10, 406 valid pixels, units unknown");
  }
  const Cube c = Store::open(dir / "db.h5").read_image("big");
  ASSERT_EQ(c.bands, 4u);
  for (std::size_t y = 0; y < 37; ++y)
    for (std::size_t x = 0; x < 11; ++x) {
      const bool planted = y == 1 && x == 2;
      ASSERT_EQ(c.valid(y, x), !planted);
      for (std::size_t b = 0; b < 4; ++b) ASSERT_EQ(c.pixel(y, x)[b], planted ? 0.0f : float(value_at(y, x, b)));
    }
  // Resampled on the way: 505 nm is halfway between bands 0 and 1.
  o.wavelengths = WavelengthGrid::range(505, 525, 10);
  o.name = "half";
  {
    StoreWriter w(dir / "db.h5", {});
    import_files(w, {dir / "big.tif"}, o);
    w.commit();
  }
  const Cube h = Store::open(dir / "db.h5").read_image("half");
  EXPECT_NEAR(h.pixel(30, 7)[0], value_at(30, 7, 0) + 500, 1e-3);
  // NaN in the data: rejected with the first position, nothing written; masked when asked.
  python(dir / "nan.tif",
         "d = gdal.GetDriverByName('GTiff').Create(out, 3, 20, 2, gdal.GDT_Float32)\n"
         "for b in range(2):\n"
         "    a = np.ones((20, 3), np.float32)\n"
         "    if b == 1: a[17, 1] = np.nan\n"
         "    d.GetRasterBand(b + 1).WriteArray(a)\n"
         "d = None\n");
  ImportOptions n;
  n.wavelengths = WavelengthGrid::range(500, 510, 10);
  n.strip_bytes = 3 * (2 * 4 + 1) * 5;  // 5 rows per strip
  const auto before = Store::open(dir / "db.h5").images();
  {
    StoreWriter w(dir / "db.h5", {});
    const std::string e = error_of([&] { import_files(w, {dir / "nan.tif"}, n); });
    EXPECT_NE(e.find("nan.tif: 1 NaN/Inf values in 1 pixels of rows 15 to 19 (first at row 17, column 1, band 1"),
              std::string::npos)
        << e;
  }
  EXPECT_EQ(Store::open(dir / "db.h5").images(), before);
  n.nan = NanPolicy::mask;
  StoreWriter w(dir / "db.h5", {});
  const ImportReport r = import_files(w, {dir / "nan.tif"}, n);
  w.commit();
  ASSERT_EQ(r.notes.size(), 1u);
  EXPECT_NE(r.notes[0].find("masked 1 pixels holding NaN/Inf"), std::string::npos) << r.notes[0];
  const Cube m = Store::open(dir / "db.h5").read_image("nan");
  EXPECT_FALSE(m.valid(17, 1));
  EXPECT_TRUE(m.valid(17, 0));
}

}  // namespace
}  // namespace specula::store
