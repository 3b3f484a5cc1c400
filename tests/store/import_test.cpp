#include "specula/store/import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/io/png_stack.h"
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
  std::ofstream(dir / "u.raw", std::ios::binary)
      .write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * 4));
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
  EXPECT_NE(test::input_error_text([&] {
              import_files(w, {dir / "nan.hdr"}, {});
            }).find("set the `nan` option to \"mask\" to keep the image"),
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

// Every image and collection of the store at `path`, with values and masks, as one comparable text.
std::string contents(const std::filesystem::path& path) {
  const Store s = Store::open(path);
  std::string out;
  for (const auto& n : s.images()) {
    const Cube c = s.read_image(n);
    out += "image " + n + " " + c.wavelengths.describe() + " " + c.provenance.source_file + ":";
    for (float v : c.data) out += " " + std::to_string(v);
    for (auto m : c.mask) out += " " + std::to_string(int(m));
    out += "\n";
  }
  for (const auto& n : s.collections()) {
    const Collection c = s.read_collection(n);
    out += "collection " + n + ":";
    for (float v : c.values) out += " " + std::to_string(v);
    out += "\n";
  }
  return out;
}

// A database directory: ENVI images (one in a subdirectory), a CSV table, a PNG band stack directory beside a
// stray thumbnail, and files no reader knows.
void write_database(const std::filesystem::path& root) {
  std::filesystem::create_directories(root / "sub");
  std::filesystem::create_directories(root / "stack");
  write_envi(root / "a", 3, 4, 3);
  write_envi(root / "b", 2, 5, 3);
  write_envi(root / "sub" / "c", 4, 2, 3);
  std::ofstream(root / "lib.csv") << "name,500,510,520\nchip,0.1,0.2,0.3\n";
  std::ofstream(root / "README") << "about this database\n";
  std::ofstream(root / "orphan.raw") << "no header";
  test::write_file(root / "stack" / "Thumbs.db", "x");
}

TEST(Import, DirectoryImportsWhatItRecognisesAndReportsEverySkip) {
  const test::ScratchDir dir;
  write_database(dir / "db");
  StoreWriter w(dir / "s.h5", {});
  ImportOptions o;
  const ImportReport r = import_files(w, {dir / "db"}, o);
  w.commit();
  ASSERT_EQ(r.imported.size(), 4u);
  EXPECT_EQ(r.imported[0].rfind("imported image a: 3x4", 0), 0u) << r.imported[0];
  EXPECT_EQ(r.imported[1].rfind("imported image b: 2x5", 0), 0u) << r.imported[1];
  EXPECT_EQ(r.imported[2].rfind("imported collection lib:", 0), 0u) << r.imported[2];
  EXPECT_EQ(r.imported[3].rfind("imported image c: 4x2", 0), 0u) << r.imported[3];
  ASSERT_EQ(r.skipped.size(), 3u);
  EXPECT_EQ(r.skipped[0].rfind((dir / "db" / "README").string() + ": skipped: cannot tell the format", 0), 0u)
      << r.skipped[0];
  EXPECT_EQ(r.skipped[1],
            (dir / "db" / "orphan.raw").string() + ": skipped: an ENVI data file without its .hdr header");
  EXPECT_EQ(r.skipped[2].rfind((dir / "db" / "stack" / "Thumbs.db").string() + ": skipped", 0), 0u) << r.skipped[2];
  // `stack` holds no PNG: only its stray file is reported. A glob picks the same files as the directory.
  const Store s = Store::open(dir / "s.h5");
  EXPECT_EQ(s.images(), (std::vector<std::string>{"a", "b", "c"}));
  StoreWriter g(dir / "g.h5", {});
  const ImportReport rg = import_files(g, {dir / "db" / "*.hdr", dir / "db" / "s*"}, o);
  g.commit();
  EXPECT_EQ(Store::open(dir / "g.h5").images(), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(rg.skipped.size(), 1u);
  StoreWriter none(dir / "n.h5", {});
  const std::string e = test::input_error_text([&] { import_files(none, {dir / "db" / "*.nothing"}, o); });
  EXPECT_NE(e.find("*.nothing: no file matches this pattern"), std::string::npos) << e;
}

TEST(Import, StrictMakesASkipAnErrorAndLeavesTheStoreAsItWas) {
  const test::ScratchDir dir;
  write_database(dir / "db");
  write_envi(dir / "first", 2, 2, 3);
  {
    StoreWriter w(dir / "s.h5", {});
    import_files(w, {dir / "first.hdr"}, {});
    w.commit();
  }
  const std::string before = contents(dir / "s.h5");
  ImportOptions o;
  o.strict = true;
  {
    StoreWriter w(dir / "s.h5", {});
    const std::string e = test::input_error_text([&] { import_files(w, {dir / "db"}, o); });
    EXPECT_NE(e.find("README: skipped: cannot tell the format"), std::string::npos) << e;
    EXPECT_NE(e.find("(3 files skipped in all); the `strict` option makes a skip an error"), std::string::npos) << e;
  }
  EXPECT_EQ(contents(dir / "s.h5"), before);
}

TEST(Import, StoreContentDoesNotDependOnJobsOrTheMemoryBudget) {
  const test::ScratchDir dir;
  write_database(dir / "db");
  for (int i = 0; i < 6; ++i) write_envi(dir / "db" / ("m" + std::to_string(i)), 5 + i, 7, 3);
  ImportOptions serial;
  StoreWriter w1(dir / "one.h5", {});
  const ImportReport r1 = import_files(w1, {dir / "db"}, serial);
  w1.commit();
  for (std::uint64_t budget : {std::uint64_t{1}, std::uint64_t{1} << 30}) {  // one file at a time, then all at once
    ImportOptions parallel;
    parallel.jobs = 2;
    parallel.memory_budget = budget;
    const auto path = dir / ("two-" + std::to_string(budget) + ".h5");
    StoreWriter w2(path, {});
    const ImportReport r2 = import_files(w2, {dir / "db"}, parallel);
    w2.commit();
    EXPECT_EQ(r2.imported, r1.imported);
    EXPECT_EQ(r2.skipped, r1.skipped);
    EXPECT_EQ(contents(path), contents(dir / "one.h5"));
  }
}

TEST(Import, WithSeveralBadFilesTheFirstOneIsReportedWhateverTheJobs) {
  const test::ScratchDir dir;
  std::filesystem::create_directories(dir / "db");
  for (int i = 0; i < 5; ++i) write_envi(dir / "db" / ("m" + std::to_string(i)), 4, 4, 3, i == 1 || i == 3 ? 5 : -1);
  for (unsigned jobs : {1u, 2u}) {
    ImportOptions o;
    o.jobs = jobs;
    StoreWriter w(dir / "s.h5", {});
    const std::string e = test::input_error_text([&] { import_files(w, {dir / "db"}, o); });
    EXPECT_EQ(e.rfind((dir / "db" / "m1.hdr").string() + ": 1 NaN/Inf values", 0), 0u) << jobs << ": " << e;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "s.h5"));
}

TEST(Import, APngStackByDirectoryOrByPatternIsOneImage) {
  const test::ScratchDir dir;
  std::filesystem::create_directories(dir / "cave");
  for (int b = 0; b < 3; ++b)
    write_png_gray16(dir / "cave" / ("band_" + std::to_string(b) + ".png"), 2, 1,
                     std::vector<std::uint16_t>{std::uint16_t(1000 * b), std::uint16_t(1000 * b + 1)});
  test::write_file(dir / "cave" / "Thumbs.db", "x");
  ImportOptions o;
  o.wavelengths = WavelengthGrid::range(500, 520, 10);
  for (const auto& in : {dir / "cave", dir / "cave" / "*.png"}) {
    StoreWriter w(dir / "s.h5", {.replace = true});
    const ImportReport r = import_files(w, {in}, o);
    w.commit();
    ASSERT_EQ(r.imported.size(), 1u) << in;
    EXPECT_EQ(r.imported[0].rfind("imported image ", 0), 0u) << r.imported[0];
    EXPECT_NE(r.imported[0].find(": 1x2, 3 bands"), std::string::npos) << r.imported[0];
  }
}

}  // namespace
}  // namespace specula::store
