// `specula import` end to end: every bad input gives one line naming the file, exit status 1, and leaves
// the store byte-identical; good input lands whole.
#include <gtest/gtest.h>
#include <matio.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <thread>
#include <tuple>
#include <vector>

#include "specula/store/h5.h"
#include "specula/store/io/png_stack.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

// Writes a small float32 BIP ENVI image whose value at (y, x, b) is y + 10x + 100b.
void write_envi(const std::filesystem::path& base, std::size_t h, std::size_t w, std::size_t b,
                const std::string& extra_header = "", float nan_at = -1, std::size_t truncate_to = 0, int data_type = 4,
                const std::string& wavelengths = "") {
  std::vector<float> v(h * w * b);
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x)
      for (std::size_t k = 0; k < b; ++k) v[(y * w + x) * b + k] = float(y + 10 * x + 100 * k);
  if (nan_at >= 0) v[std::size_t(nan_at)] = std::nanf("");
  std::string wl = wavelengths;
  if (wl.empty()) {
    for (std::size_t k = 0; k < b; ++k) wl += (k ? ", " : "") + std::to_string(420 + 10 * k);
  }
  std::ofstream hdr(base.string() + ".hdr");
  hdr << "ENVI\nsamples = " << w << "\nlines = " << h << "\nbands = " << b << "\nheader offset = 0\n"
      << "data type = " << data_type << "\ninterleave = bip\nbyte order = 0\nwavelength units = Nanometers\n"
      << "wavelength = {" << wl << "}\n"
      << extra_header;
  std::ofstream raw(base.string() + ".raw", std::ios::binary);
  const std::size_t bytes = truncate_to ? truncate_to : v.size() * 4;
  raw.write(reinterpret_cast<const char*>(v.data()), std::streamsize(bytes));
}

std::filesystem::path make_store(const test::ScratchDir& dir) {
  auto store = dir / "db.h5";
  write_envi(dir / "good", 6, 5, 31);
  auto r = run_specula("-q import '" + (dir / "good.hdr").string() + "' -o '" + store.string() + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  return store;
}

// Runs a failing import and checks the contract: exit 1, one line, names `names`, store unchanged.
void expect_rejected(const test::ScratchDir& dir, const std::string& args, const std::string& names,
                     const std::string& says) {
  auto store = dir / "db.h5";
  const std::string before = test::read_bytes(store);
  auto r = run_specula("-q import " + args + " -o '" + store.string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_NE(r.output.find(names), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
  EXPECT_EQ(test::read_bytes(store), before) << "the store changed";
  for (auto& e : std::filesystem::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << "left behind: " << e.path();
}

}  // namespace

TEST(ImportCli, GoodEnviLandsWithItsValues) {
  test::ScratchDir dir;
  auto store = make_store(dir);
  auto s = store::Store::open(store);
  auto cube = s.read_image("good");
  ASSERT_EQ(cube.bands, 31u);
  EXPECT_EQ(cube.pixel(3, 4)[2], float(3 + 40 + 200));
  EXPECT_EQ(cube.provenance.importer, "envi");
  EXPECT_NE(cube.provenance.command_line.find("import"), std::string::npos);
}

TEST(ImportCli, TruncatedRawFile) {
  test::ScratchDir dir;
  make_store(dir);
  write_envi(dir / "cut", 6, 5, 31, "", -1, 100);
  expect_rejected(dir, "'" + (dir / "cut.hdr").string() + "'", "cut", "bytes");
}

TEST(ImportCli, HeaderSizeMismatch) {
  test::ScratchDir dir;
  make_store(dir);
  write_envi(dir / "big", 6, 5, 31);
  std::ofstream(dir / "big.raw", std::ios::app) << "extra bytes that the header does not describe";
  expect_rejected(dir, "'" + (dir / "big.hdr").string() + "'", "big", "bytes");
}

TEST(ImportCli, UnknownDataType) {
  test::ScratchDir dir;
  make_store(dir);
  write_envi(dir / "dt", 6, 5, 31, "", -1, 0, 7);
  expect_rejected(dir, "'" + (dir / "dt.hdr").string() + "'", "dt.hdr", "data type");
}

// Issue 18: an unsorted band list is kept, sorted with its values; a wavelength listed twice is refused.
TEST(ImportCli, NonMonotonicWavelengthsAreSortedWithTheirBands) {
  test::ScratchDir dir;
  const auto store = make_store(dir);
  write_envi(dir / "wl", 2, 2, 3, "", -1, 0, 4, "500, 490, 510");
  auto r = run_specula("-q import '" + (dir / "wl.hdr").string() + "' -o '" + store.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Cube c = store::Store::open(store).read_image("wl");
  EXPECT_EQ(std::vector<double>(c.wavelengths.values().begin(), c.wavelengths.values().end()),
            (std::vector<double>{490, 500, 510}));
  EXPECT_EQ(std::vector<float>(c.data.begin(), c.data.begin() + 3), (std::vector<float>{100, 0, 200}));
  write_envi(dir / "twice", 2, 2, 3, "", -1, 0, 4, "500, 490, 500");
  expect_rejected(dir, "'" + (dir / "twice.hdr").string() + "'", "twice", "wavelength 500 appears twice");
}

TEST(ImportCli, TargetGridOutsideTheDataIsRefused) {
  test::ScratchDir dir;
  make_store(dir);
  expect_rejected(dir, "'" + (dir / "good.hdr").string() + "' --name again --wavelengths 380:780:10", "good",
                  "extrapolation");
}

TEST(ImportCli, NanIsRejectedWithCountAndPositionOrMasked) {
  test::ScratchDir dir;
  auto store = make_store(dir);
  write_envi(dir / "nan", 6, 5, 31, "", float((2 * 5 + 3) * 31 + 4));
  expect_rejected(dir, "'" + (dir / "nan.hdr").string() + "'", "nan",
                  "1 NaN/Inf values in 1 pixels (first at row 2, column 3, band 4 = 460 nm)");
  expect_rejected(dir, "'" + (dir / "nan.hdr").string() + "'", "nan", "set --nan to \"mask\"");
  auto r = run_specula("-q import '" + (dir / "nan.hdr").string() + "' --nan mask -o '" + store.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  auto info = store::Store::open(store).image_info("nan");
  EXPECT_EQ(info.valid_pixels, 29u);
}

TEST(ImportCli, MatWithoutTheNamedVariable) {
  test::ScratchDir dir;
  make_store(dir);
  auto mat = dir / "scene.mat";
  mat_t* f = Mat_CreateVer(mat.c_str(), nullptr, MAT_FT_MAT5);
  ASSERT_NE(f, nullptr);
  double data[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  std::size_t dims[3] = {2, 2, 2};
  matvar_t* v = Mat_VarCreate("rad", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, data, 0);
  Mat_VarWrite(f, v, MAT_COMPRESSION_NONE);
  Mat_VarFree(v);
  Mat_Close(f);
  expect_rejected(dir, "'" + mat.string() + "' --var ref --wavelengths 500,600", "scene.mat", "rad");
}

TEST(ImportCli, CorruptOrForeignStoreIsNotTouched) {
  test::ScratchDir dir;
  write_envi(dir / "good", 6, 5, 31);
  // A text file posing as a store.
  auto fake = dir / "db.h5";
  std::ofstream(fake) << "not hdf5 at all";
  expect_rejected(dir, "'" + (dir / "good.hdr").string() + "'", "db.h5", "not an HDF5 file");
  // An HDF5 file that is not a specula store.
  std::filesystem::remove(fake);
  H5Fclose(H5Fcreate(fake.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
  expect_rejected(dir, "'" + (dir / "good.hdr").string() + "'", "db.h5", "not a specula store");
}

TEST(ImportCli, FullDiskDuringImport) {
  test::ScratchDir dir;
  make_store(dir);
  write_envi(dir / "more", 64, 64, 31);
  ::setenv("SPECULA_INJECT_WRITE_FAILURE", "0", 1);
  expect_rejected(dir, "'" + (dir / "more.hdr").string() + "'", "db.h5", "No space left on device");
  ::unsetenv("SPECULA_INJECT_WRITE_FAILURE");
}

TEST(ImportCli, AllFilesOrNone) {
  test::ScratchDir dir;
  make_store(dir);
  write_envi(dir / "fine", 4, 4, 31);
  write_envi(dir / "cut", 6, 5, 31, "", -1, 10);
  expect_rejected(dir, "'" + (dir / "fine.hdr").string() + "' '" + (dir / "cut.hdr").string() + "'", "cut", "bytes");
  EXPECT_EQ(store::Store::open(dir / "db.h5").images(), std::vector<std::string>{"good"});
}

TEST(ImportCli, KilledOrInterruptedImportLeavesTheStoreAsItWas) {
  test::ScratchDir dir;
  auto store = make_store(dir);
  const std::string before = test::read_bytes(store);
  const auto images = dir / "db.h5.d" / "objects" / "images";
  auto data_files = [&] {
    return std::distance(std::filesystem::directory_iterator(images), std::filesystem::directory_iterator());
  };
  const auto committed = data_files();
  for (int sig : {SIGKILL, SIGINT}) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::execl(SPECULA_BINARY, SPECULA_BINARY, "-q", "synth-db", "-o", store.c_str(), "--images", "400", "--size",
              "256x256", "--compression", "deflate:9", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    // Wait until the transaction writes its first data file, then stop the writer.
    bool started = false;
    for (int i = 0; i < 400 && !started; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
      started = data_files() > committed;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ::kill(pid, sig);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(started);
    if (sig == SIGKILL) {
      EXPECT_EQ(test::read_bytes(store), before) << "kill -9 changed the store";
      EXPECT_GT(data_files(), committed) << "the killed writer's data files are there until collected";
      ASSERT_EQ(run_specula("gc '" + store.string() + "'").status, 0);
      EXPECT_EQ(data_files(), committed) << "gc did not reclaim the killed transaction's files";
    } else {
      // Ctrl-C: synth-db keeps the images it finished (possibly none); the store is a valid store either way.
      EXPECT_EQ(WEXITSTATUS(status), 130);
      auto s = store::Store::open(store);
      EXPECT_EQ(s.images().front(), "good");
      EXPECT_EQ(data_files(), std::ptrdiff_t(s.images().size())) << "an unfinished image's data file was left";
      EXPECT_TRUE(store::check(store).empty());
      for (auto& e : std::filesystem::directory_iterator(dir.path()))
        EXPECT_EQ(e.path().string().find(".commit-"), std::string::npos) << "left behind: " << e.path();
    }
  }
}

TEST(ImportCli, CaveStylePngStackWithMaskAndResampling) {
  test::ScratchDir dir;
  std::filesystem::create_directories(dir / "balloons_ms");
  const std::size_t w = 4, h = 3;
  // Band k at pixel p holds 1000 * (k + 1) + p, so linear resampling halfway between bands is checkable.
  for (std::size_t k = 0; k < 3; ++k) {
    std::vector<std::uint16_t> v(w * h);
    for (std::size_t p = 0; p < w * h; ++p) v[p] = std::uint16_t(1000 * (k + 1) + p);
    char name[64];
    std::snprintf(name, sizeof name, "balloons_ms_%02zu.png", k + 1);
    store::write_png_gray16(dir / "balloons_ms" / name, w, h, v);
  }
  std::vector<std::uint8_t> mask(3 * w * h, 255);
  mask[3 * 5] = mask[3 * 5 + 1] = mask[3 * 5 + 2] = 0;
  store::write_png_rgb8(dir / "mask.png", w, h, mask);
  auto db = dir / "db.h5";
  auto r = run_specula("-q import '" + (dir / "balloons_ms").string() + "' -o '" + db.string() +
                       "' --source-wavelengths 400:420:10 --wavelengths 405:415:5 --mask '" +
                       (dir / "mask.png").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  auto cube = store::Store::open(db).read_image("balloons_ms");
  ASSERT_EQ(cube.bands, 3u);
  EXPECT_EQ(cube.mask[5], 0);
  EXPECT_EQ(std::count(cube.mask.begin(), cube.mask.end(), 1), 11);
  for (std::size_t p : {0u, 7u, 11u})
    for (std::size_t k = 0; k < 3; ++k)  // 405, 410, 415 nm: bands 0.5, 1, 1.5 of the source
      EXPECT_NEAR(cube.data[p * 3 + k], (1000.0 * (1.5 + 0.5 * double(k)) + double(p)) / 65535.0, 1e-6);
  // Without a grid the stack cannot be imported.
  r = run_specula("-q import '" + (dir / "balloons_ms").string() + "' -o '" + (dir / "x.h5").string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--wavelengths"), std::string::npos) << r.output;
}

TEST(ImportCli, RealColorCheckerImageAndMunsellTable) {
  SPECULA_REQUIRE_SHARED();
  test::ScratchDir dir;
  auto db = dir / "db.h5";
  const auto data = test::shared_dir() / "data";
  auto r = run_specula("-q import '" + (data / "images/Macbeth.exr").string() + "' '" +
                       (data / "reflectance/munsell_matt_1269_380-780_5nm.csv").string() + "' -o '" + db.string() +
                       "' --wavelengths 420:720:10");
  ASSERT_EQ(r.status, 0) << r.output;
  auto s = store::Store::open(db);
  auto macbeth = s.image_info("Macbeth");
  EXPECT_EQ(macbeth.height, 400u);
  EXPECT_EQ(macbeth.width, 600u);
  EXPECT_EQ(macbeth.bands, 31u);
  EXPECT_EQ(macbeth.units, "reflectance");
  auto munsell = s.read_collection("munsell_matt_1269_380-780_5nm");
  ASSERT_EQ(munsell.size(), 1269u);
  EXPECT_EQ(munsell.names[0], "2.5R9/2");
  // 2.5R9/2 at 420 nm is 0.69536 in the file (column 420).
  EXPECT_NEAR(munsell.values[0], 0.69536f, 1e-6f);
}

TEST(ImportCli, EnviWithoutWavelengthsTakesTheFlagAndNamesIt) {
  const test::ScratchDir dir;
  {
    std::ofstream hdr(dir / "bare.hdr");
    hdr << "ENVI\nsamples = 2\nlines = 1\nbands = 3\nheader offset = 0\ndata type = 4\ninterleave = bip\nbyte order = "
           "0\n";
    const std::vector<float> v{1, 2, 3, 4, 5, 6};
    std::ofstream(dir / "bare.raw", std::ios::binary).write(reinterpret_cast<const char*>(v.data()), 24);
  }
  const std::string in = "'" + (dir / "bare.hdr").string() + "'";
  const std::string out = " -o '" + (dir / "db.h5").string() + "'";
  auto r = run_specula("-q import " + in + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("bare.hdr: the header has no wavelengths; give --wavelengths FIRST:LAST:STEP"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "db.h5"));
  r = run_specula("-q import " + in + " --wavelengths 400:600:100" + out);
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Cube c = store::Store::open(dir / "db.h5").read_image("bare");
  EXPECT_EQ(c.wavelengths.describe(), store::Store::open(dir / "db.h5").image_info("bare").wavelengths.describe());
  EXPECT_EQ(c.wavelengths[2], 600.0);
  EXPECT_EQ(c.data, (std::vector<float>{1, 2, 3, 4, 5, 6}));
}

TEST(ImportCli, EnviByteMaskMasksTheImage) {
  const test::ScratchDir dir;
  write_envi(dir / "scene", 2, 3, 4);
  {
    std::ofstream(dir / "roi.hdr") << "ENVI\nsamples = 3\nlines = 2\nbands = 1\nheader offset = 0\ndata type = 1\n"
                                      "interleave = bsq\nbyte order = 0\n";
    const std::uint8_t roi[6] = {1, 0, 1, 1, 1, 0};
    std::ofstream(dir / "roi.img", std::ios::binary).write(reinterpret_cast<const char*>(roi), 6);
  }
  const std::string store = "'" + (dir / "db.h5").string() + "'";
  auto r = run_specula("-q import '" + (dir / "scene.hdr").string() + "' --mask '" + (dir / "roi.img").string() +
                       "' -o " + store);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(store::Store::open(dir / "db.h5").read_image("scene").mask, (std::vector<std::uint8_t>{1, 0, 1, 1, 1, 0}));
  // A mask of another size: one line, the store as it was.
  const std::string before = test::read_bytes(dir / "db.h5");
  write_envi(dir / "big", 3, 3, 4);
  r = run_specula("-q import '" + (dir / "big.hdr").string() + "' --mask '" + (dir / "roi.hdr").string() + "' -o " +
                  store);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("roi.hdr: mask is 3x2, image is 3x3"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_bytes(dir / "db.h5"), before);
}

namespace {
// Writes one double variable of MATLAB dims `dims` (column-major values) per entry.
void write_mat_vars(const std::filesystem::path& p, mat_ft version,
                    const std::vector<std::tuple<std::string, std::vector<std::size_t>, std::vector<double>>>& vars) {
  mat_t* f = Mat_CreateVer(p.c_str(), nullptr, version);
  ASSERT_NE(f, nullptr);
  for (auto [name, dims, values] : vars) {
    matvar_t* v =
        Mat_VarCreate(name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, int(dims.size()), dims.data(), values.data(), 0);
    ASSERT_NE(v, nullptr);
    EXPECT_EQ(Mat_VarWrite(f, v, MAT_COMPRESSION_NONE), 0);
    Mat_VarFree(v);
  }
  Mat_Close(f);
}
}  // namespace

TEST(ImportCli, MatLayoutsDetectedWithoutVar) {
  test::ScratchDir dir;
  auto db = dir / "db.h5";
  // ARAD-1K: cube bands x rows x cols (v7.3) + bands; value at (r, c, b) = r + 10c + 100b.
  const std::size_t h = 2, w = 3, b = 4;
  std::vector<double> cube(h * w * b), y(h * w * b);
  for (std::size_t r = 0; r < h; ++r)
    for (std::size_t c = 0; c < w; ++c)
      for (std::size_t k = 0; k < b; ++k) {
        cube[k + b * (r + h * c)] = double(r + 10 * c + 100 * k);
        y[k + b * (r + h * c)] = double(r + 10 * c + 100 * k);  // Jasper Ridge Y bands x pixels, p = r + nRow c
      }
  write_mat_vars(dir / "arad.mat", MAT_FT_MAT73, {{"cube", {b, h, w}, cube}, {"bands", {1, b}, {400, 410, 420, 430}}});
  write_mat_vars(dir / "jasper.mat", MAT_FT_MAT5,
                 {{"Y", {b, h * w}, y}, {"nRow", {1, 1}, {double(h)}}, {"nCol", {1, 1}, {double(w)}}});
  // ISETCam library: wavelength 4 x 1, data 4 x 2 (spectra as columns).
  write_mat_vars(
      dir / "lib.mat", MAT_FT_MAT5,
      {{"wavelength", {b, 1}, {400, 410, 420, 430}}, {"data", {b, 2}, {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8}}});
  auto r = run_specula("-q import '" + (dir / "arad.mat").string() + "' '" + (dir / "lib.mat").string() + "' -o '" +
                       db.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("-q import '" + (dir / "jasper.mat").string() + "' --wavelengths 400:430:10 -o '" + db.string() +
                  "'");
  ASSERT_EQ(r.status, 0) << r.output;
  auto s = store::Store::open(db);
  for (const char* name : {"arad", "jasper"}) {
    SCOPED_TRACE(name);
    auto img = s.read_image(name);
    ASSERT_EQ(img.height, h);
    ASSERT_EQ(img.width, w);
    ASSERT_EQ(img.bands, b);
    EXPECT_EQ(img.pixel(1, 2)[3], float(1 + 20 + 300));
    EXPECT_EQ(img.pixel(0, 1)[1], float(0 + 10 + 100));
    EXPECT_EQ(img.wavelengths[3], 430.0);
  }
  auto lib = s.read_collection("lib");
  ASSERT_EQ(lib.size(), 2u);
  EXPECT_EQ(lib.names[1], "data_2");
  EXPECT_EQ(lib.values[1 * b + 2], 0.7f);
  EXPECT_EQ(lib.provenance.importer, "mat");
}

TEST(ImportCli, MatWithoutWavelengthsAsksForTheFlag) {
  test::ScratchDir dir;
  make_store(dir);
  auto mat = dir / "Indian_pines_corrected.mat";
  write_mat_vars(mat, MAT_FT_MAT5, {{"indian_pines_corrected", {2, 2, 3}, std::vector<double>(12, 1.0)}});
  expect_rejected(dir, "'" + mat.string() + "'", "Indian_pines_corrected.mat",
                  "bands of 'indian_pines_corrected'; give --wavelengths FIRST:LAST:STEP");
}

TEST(ImportCli, MatWithSeveralCubesAsksForVar) {
  test::ScratchDir dir;
  make_store(dir);
  auto mat = dir / "two.mat";
  write_mat_vars(mat, MAT_FT_MAT5,
                 {{"a", {2, 2, 3}, std::vector<double>(12, 1.0)}, {"b", {2, 2, 3}, std::vector<double>(12, 2.0)}});
  expect_rejected(dir, "'" + mat.string() + "' --wavelengths 400:420:10", "two.mat",
                  "(a, b) and none of the known names");
  expect_rejected(dir, "'" + mat.string() + "' --wavelengths 400:420:10", "two.mat", "give its name as --var");
}

TEST(ImportCli, DirectoryAndQuotedGlobInOneCommandNameEverySkip) {
  test::ScratchDir dir;
  auto store = make_store(dir);
  std::filesystem::create_directories(dir / "db" / "more");
  write_envi(dir / "db" / "a", 3, 4, 31);
  write_envi(dir / "db" / "more" / "b", 2, 2, 31);
  std::ofstream(dir / "db" / "notes.md") << "about\n";
  // --strict: one line naming the skipped file and the flag, exit 1, the store byte-identical.
  expect_rejected(dir, "'" + (dir / "db").string() + "' --strict", "notes.md: skipped",
                  "--strict makes a skip an error");
  auto r = run_specula("-q import '" + (dir / "db").string() + "' -o '" + store.string() + "' --jobs 2");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find((dir / "db" / "notes.md").string() + ": skipped: cannot tell the format from the extension "
                                                               "'.md'; give --format"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("imported image a: 3x4"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("imported image b: 2x2"), std::string::npos) << r.output;
  // The shell does not expand a quoted pattern; specula does.
  r = run_specula("-q import '" + (dir / "db" / "*.hdr").string() + "' -o '" + (dir / "g.h5").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(store::Store::open(dir / "g.h5").images(), std::vector<std::string>{"a"});
  expect_rejected(dir, "'" + (dir / "db" / "*.tif").string() + "'", "*.tif", "no file matches this pattern");
}
