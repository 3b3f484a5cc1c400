#include "specula/store/io/mat.h"

#include <matio.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::store {
namespace {

using test::ScratchDir;

struct MatVar {
  std::string name;
  matio_classes cls;
  matio_types type;
  std::vector<std::size_t> dims;
  std::vector<unsigned char> bytes;  // column-major element bytes
  int flags = 0;
};

template <typename T>
MatVar make_var(const std::string& name, matio_classes cls, matio_types type, std::vector<std::size_t> dims,
                const std::vector<T>& values, int flags = 0) {
  MatVar v{name, cls, type, std::move(dims), {}, flags};
  v.bytes.resize(values.size() * sizeof(T));
  std::memcpy(v.bytes.data(), values.data(), v.bytes.size());
  return v;
}

// Writes the variables with matio itself; returns false when this matio cannot create `version` files.
bool write_mat(const std::filesystem::path& p, mat_ft version, const std::vector<MatVar>& vars,
               matio_compression compression = MAT_COMPRESSION_NONE) {
  mat_t* mat = Mat_CreateVer(p.c_str(), nullptr, version);
  if (!mat) return false;
  for (const auto& v : vars) {
    std::vector<std::size_t> dims = v.dims;
    std::vector<unsigned char> bytes = v.bytes;
    matvar_t* mv =
        Mat_VarCreate(v.name.c_str(), v.cls, v.type, static_cast<int>(dims.size()), dims.data(), bytes.data(), v.flags);
    EXPECT_NE(mv, nullptr) << v.name;
    if (!mv) break;
    EXPECT_EQ(Mat_VarWrite(mat, mv, compression), 0) << v.name;
    Mat_VarFree(mv);
  }
  EXPECT_EQ(Mat_Close(mat), 0);
  return true;
}

constexpr std::size_t kRows = 3, kCols = 4, kBands = 5;
double f(std::size_t r, std::size_t c, std::size_t b) { return 100.0 * r + 10.0 * c + b; }

// Column-major: element (r, c, b) at r + rows * (c + cols * b).
template <typename T>
std::vector<T> column_major(double offset = 0) {
  std::vector<T> out(kRows * kCols * kBands);
  for (std::size_t r = 0; r < kRows; ++r)
    for (std::size_t c = 0; c < kCols; ++c)
      for (std::size_t b = 0; b < kBands; ++b) out[r + kRows * (c + kCols * b)] = static_cast<T>(f(r, c, b) + offset);
  return out;
}

void expect_cube(const Cube& cube, double offset = 0) {
  ASSERT_EQ(cube.height, kRows);
  ASSERT_EQ(cube.width, kCols);
  ASSERT_EQ(cube.bands, kBands);
  for (std::size_t r = 0; r < kRows; ++r)
    for (std::size_t c = 0; c < kCols; ++c)
      for (std::size_t b = 0; b < kBands; ++b)
        EXPECT_EQ(cube.pixel(r, c)[b], static_cast<float>(f(r, c, b) + offset)) << r << "," << c << "," << b;
}

const std::vector<double> kNm = {400, 450, 500, 550, 600};

MatVar ref_double() {
  return make_var("ref", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols, kBands}, column_major<double>(0.5));
}
MatVar wl_var(const std::string& name = "wavelengths") {
  return make_var(name, MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, kNm);
}

TEST(Mat, V5ColumnMajorDoubleWithWavelengths) {
  ScratchDir dir;
  ASSERT_TRUE(write_mat(dir / "a.mat", MAT_FT_MAT5, {wl_var(), ref_double()}));
  const Cube cube = read_mat(dir / "a.mat", "ref", std::nullopt, {});
  expect_cube(cube, 0.5);
  ASSERT_EQ(cube.wavelengths.size(), kBands);
  EXPECT_EQ(cube.wavelengths[0], 400.0);
  EXPECT_EQ(cube.wavelengths[4], 600.0);
  EXPECT_TRUE(cube.mask.empty());
  EXPECT_EQ(cube.provenance.importer, "mat");
}

TEST(Mat, V5CompressedAndBandsVariable) {
  ScratchDir dir;
  ASSERT_TRUE(write_mat(dir / "z.mat", MAT_FT_MAT5, {ref_double(), wl_var("bands")}, MAT_COMPRESSION_ZLIB));
  const Cube cube = read_mat(dir / "z.mat", "ref", std::nullopt, WavelengthGrid::range(700, 740, 10));
  expect_cube(cube, 0.5);
  EXPECT_EQ(cube.wavelengths[1], 450.0);  // the file's variable wins over the argument
}

TEST(Mat, V73ColumnMajor) {
  ScratchDir dir;
  if (!write_mat(dir / "h.mat", MAT_FT_MAT73, {ref_double(), wl_var()}))
    GTEST_SKIP() << "this matio cannot create v7.3 files (built without HDF5)";
  mat_t* m = Mat_Open((dir / "h.mat").c_str(), MAT_ACC_RDONLY);
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(Mat_GetVersion(m), MAT_FT_MAT73);
  Mat_Close(m);
  const Cube cube = read_mat(dir / "h.mat", "ref", std::nullopt, {});
  expect_cube(cube, 0.5);
  EXPECT_EQ(cube.wavelengths[2], 500.0);
}

TEST(Mat, IntegerAndSingleClassesConvert) {
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    SCOPED_TRACE(version == MAT_FT_MAT5 ? "v5" : "v7.3");
    ScratchDir dir;
    const std::vector<std::size_t> dims = {kRows, kCols, kBands};
    const std::vector<std::pair<MatVar, double>> cases = {
        {make_var("s", MAT_C_SINGLE, MAT_T_SINGLE, dims, column_major<float>(0.25)), 0.25},
        {make_var("u8", MAT_C_UINT8, MAT_T_UINT8, dims, column_major<std::uint8_t>()), 0.0},
        {make_var("u16", MAT_C_UINT16, MAT_T_UINT16, dims, column_major<std::uint16_t>(1000)), 1000.0},
        {make_var("i16", MAT_C_INT16, MAT_T_INT16, dims, column_major<std::int16_t>(-400)), -400.0},
    };
    std::vector<MatVar> vars;
    for (const auto& c : cases) vars.push_back(c.first);
    if (!write_mat(dir / "t.mat", version, vars)) GTEST_SKIP() << "no v7.3 support in this matio";
    for (const auto& [var, offset] : cases) {
      SCOPED_TRACE(var.name);
      expect_cube(read_mat(dir / "t.mat", var.name, std::nullopt, WavelengthGrid(kNm)), offset);
    }
  }
}

TEST(Mat, MaskVariableLogicalUint8Double) {
  // Column-major 3 x 4 mask: invalid pixels (r, c) = (0, 1), (2, 3), (1, 0).
  std::vector<std::uint8_t> valid(kRows * kCols, 1);
  valid[0 + kRows * 1] = 0;
  valid[2 + kRows * 3] = 0;
  valid[1 + kRows * 0] = 0;
  std::vector<double> valid_d(valid.begin(), valid.end());
  valid_d[1] = 0.0;
  valid_d[5] = -2.0;  // nonzero = valid; (2, 1)
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    ScratchDir dir;
    const std::vector<MatVar> vars = {ref_double(),
                                      wl_var(),
                                      make_var("lmask", MAT_C_UINT8, MAT_T_UINT8, {kRows, kCols}, valid, MAT_F_LOGICAL),
                                      make_var("umask", MAT_C_UINT8, MAT_T_UINT8, {kRows, kCols}, valid),
                                      make_var("dmask", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols}, valid_d),
                                      make_var("badmask", MAT_C_UINT8, MAT_T_UINT8, {kCols, kRows}, valid)};
    if (!write_mat(dir / "m.mat", version, vars)) GTEST_SKIP() << "no v7.3 support in this matio";
    for (const char* name : {"lmask", "umask", "dmask"}) {
      SCOPED_TRACE(name);
      const Cube cube = read_mat(dir / "m.mat", "ref", std::string(name), {});
      ASSERT_EQ(cube.mask.size(), kRows * kCols);
      for (std::size_t r = 0; r < kRows; ++r)
        for (std::size_t c = 0; c < kCols; ++c) {
          const bool expected = !((r == 0 && c == 1) || (r == 2 && c == 3) || (r == 1 && c == 0));
          EXPECT_EQ(cube.valid(r, c), expected) << r << "," << c;
        }
      expect_cube(cube, 0.5);
    }
    const std::string msg = test::error_of([&] { read_mat(dir / "m.mat", "ref", std::string("badmask"), {}); });
    EXPECT_NE(msg.find("mask variable 'badmask' is 4 x 3 but 'ref' is 3 x 4"), std::string::npos) << msg;
    const std::string none = test::error_of([&] { read_mat(dir / "m.mat", "ref", std::string("nomask"), {}); });
    EXPECT_NE(none.find("no mask variable 'nomask'"), std::string::npos) << none;
  }
}

TEST(Mat, MissingVariableListsVariables) {
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    ScratchDir dir;
    const auto p = dir / "file.mat";
    const std::vector<double> one = {1};
    if (!write_mat(p, version,
                   {make_var("a", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, one),
                    make_var("b", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, one),
                    make_var("c", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, one)}))
      GTEST_SKIP() << "no v7.3 support in this matio";
    EXPECT_EQ(test::error_of([&] { read_mat(p, "ref", std::nullopt, WavelengthGrid(kNm)); }),
              p.string() + ": no variable 'ref' (variables: a, b, c)");
  }
}

TEST(Mat, BadInputs) {
  ScratchDir dir;
  const std::vector<std::int64_t> big(kRows * kCols * kBands, 7);
  const std::vector<double> short_wl = {400, 500};
  ASSERT_TRUE(write_mat(dir / "b.mat", MAT_FT_MAT5,
                        {ref_double(), make_var("i64", MAT_C_INT64, MAT_T_INT64, {kRows, kCols, kBands}, big)}));
  std::string m = test::error_of([&] { read_mat(dir / "b.mat", "ref", std::nullopt, {}); });
  EXPECT_NE(m.find("b.mat: no wavelength variable (wavelength, wavelengths, bands, wl or lambda) for the 5 bands of "
                   "'ref'; give the `wavelengths` option"),
            std::string::npos)
      << m;
  m = test::error_of([&] { read_mat(dir / "b.mat", "ref", std::nullopt, WavelengthGrid(short_wl)); });
  EXPECT_NE(m.find("has 5 bands but the `wavelengths` option gives 2"), std::string::npos) << m;
  m = test::error_of([&] { read_mat(dir / "b.mat", "i64", std::nullopt, WavelengthGrid(kNm)); });
  EXPECT_NE(m.find("variable 'i64' is int64; convert it to double"), std::string::npos) << m;

  ASSERT_TRUE(write_mat(dir / "w.mat", MAT_FT_MAT5,
                        {ref_double(), make_var("wavelengths", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 2}, short_wl)}));
  m = test::error_of([&] { read_mat(dir / "w.mat", "ref", std::nullopt, {}); });
  EXPECT_NE(m.find("variable 'wavelengths' is double 1 x 2 but 'ref' has 5 bands"), std::string::npos) << m;
  const Cube overridden = read_mat(dir / "w.mat", "ref", std::nullopt, WavelengthGrid::range(700, 740, 10));
  EXPECT_EQ(overridden.wavelengths[4], 740.0);

  {
    std::ofstream junk(dir / "junk.mat", std::ios::binary);
    junk << std::string(300, 'x');
  }
  m = test::error_of([&] { read_mat(dir / "junk.mat", "ref", std::nullopt, WavelengthGrid(kNm)); });
  EXPECT_NE(m.find("junk.mat: not a MATLAB .mat file"), std::string::npos) << m;
  m = test::error_of([&] { read_mat(dir / "absent.mat", "ref", std::nullopt, WavelengthGrid(kNm)); });
  EXPECT_NE(m.find("absent.mat: no such file"), std::string::npos) << m;
}

// Found by fuzzing (tests/fuzz/corpus/mat/): a corrupt length field that would make matio allocate and clear
// gigabytes, dimensions promising more values than the data holds (matio reads them without complaint, we
// allocated the promise), a variable name with a newline, and an nRow no size_t can hold are each one line naming
// the file.
TEST(Mat, CorruptFilesFoundByFuzzingAreOneLine) {
  ScratchDir dir;
  const std::vector<double> px = {1, 2, 3, 4, 5, 6};
  ASSERT_TRUE(write_mat(dir / "y.mat", MAT_FT_MAT5,
                        {make_var("Y", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 6}, px),
                         make_var("nRow", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, std::vector<double>{1e300}),
                         make_var("nCol", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, std::vector<double>{2.5})}));
  std::string m = test::error_of([&] { read_mat(dir / "y.mat", "", std::nullopt, WavelengthGrid({500.0})); });
  EXPECT_NE(m.find("y.mat: nRow = 1e+300 is not a whole number of pixels up to 2^31"), std::string::npos) << m;

  // The first matrix's name tag (after 128 header bytes, the matrix tag, flags and dims of a 1 x 6 matrix).
  std::string bytes;
  {
    std::ifstream in(dir / "y.mat", std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::size_t name_tag = 128 + 8 + 16 + 16;
  ASSERT_EQ(bytes.substr(name_tag + 4, 4), std::string("Y\0\0\0", 4)) << "a small data element holding 'Y'";
  std::string big = bytes;
  big.replace(name_tag, 8, std::string("\x01\0\0\0\0\0\xf8\xff", 8));  // int8, 4294443008 bytes
  test::write_file(dir / "big.mat", big);
  m = test::error_of([&] { read_mat(dir / "big.mat", "", std::nullopt, {}); });
  EXPECT_NE(m.find("big.mat: corrupt MATLAB v5 file: the element at byte 168 claims 4294443008 bytes"),
            std::string::npos)
      << m;

  std::string promise = bytes;  // dims 1 x 6 -> 1 x 600000000 (0x23c34600), the data still 6 doubles
  promise.replace(128 + 8 + 16 + 12, 4, std::string("\x00\x46\xc3\x23", 4));
  test::write_file(dir / "promise.mat", promise);
  m = test::error_of([&] { read_mat(dir / "promise.mat", "", std::nullopt, {}); });
  EXPECT_NE(m.find("promise.mat: corrupt MATLAB v5 file: the variable at byte 136 has dimensions for 600000000 values "
                   "but its data holds 6"),
            std::string::npos)
      << m;

  std::string newline = bytes;
  newline[name_tag + 4] = '\n';
  test::write_file(dir / "nl.mat", newline);
  m = test::error_of([&] { read_mat(dir / "nl.mat", "", std::nullopt, {}); });
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  EXPECT_NE(m.find("nl.mat: "), std::string::npos) << m;
}

TEST(Mat, TwoDimensionalVariableIsOneBand) {
  ScratchDir dir;
  const std::vector<float> plane = {1, 2, 3, 4, 5, 6};  // 2 x 3 column-major: (r, c) = r + 2c + 1
  ASSERT_TRUE(write_mat(dir / "p.mat", MAT_FT_MAT5, {make_var("img", MAT_C_SINGLE, MAT_T_SINGLE, {2, 3}, plane)}));
  const Cube cube = read_mat(dir / "p.mat", "img", std::nullopt, WavelengthGrid(std::vector<double>{550}));
  ASSERT_EQ(cube.height, 2u);
  ASSERT_EQ(cube.width, 3u);
  ASSERT_EQ(cube.bands, 1u);
  EXPECT_EQ(cube.pixel(0, 0)[0], 1.0f);
  EXPECT_EQ(cube.pixel(1, 0)[0], 2.0f);
  EXPECT_EQ(cube.pixel(0, 2)[0], 5.0f);
  EXPECT_EQ(cube.pixel(1, 2)[0], 6.0f);
}

// ---- Layouts of public databases: each fixture plants f(r, c, b) and reads it back at (r, c, b).

// Bands first: element (b, r, c) at b + bands * (r + rows * c), as matio reports a B x H x W variable.
std::vector<float> bands_first() {
  std::vector<float> out(kRows * kCols * kBands);
  for (std::size_t r = 0; r < kRows; ++r)
    for (std::size_t c = 0; c < kCols; ++c)
      for (std::size_t b = 0; b < kBands; ++b) out[b + kBands * (r + kRows * c)] = static_cast<float>(f(r, c, b));
  return out;
}

TEST(MatLayouts, HarvardRefWithLblMaskDetected) {
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    ScratchDir dir;
    std::vector<std::uint8_t> lbl(kRows * kCols, 1);
    lbl[2 + kRows * 1] = 0;  // (2, 1) invalid
    if (!write_mat(dir / "img1.mat", version,
                   {ref_double(), make_var("lbl", MAT_C_UINT8, MAT_T_UINT8, {kRows, kCols}, lbl)}))
      GTEST_SKIP() << "no v7.3 support in this matio";
    EXPECT_EQ(mat_kind(dir / "img1.mat"), MatKind::image);
    const Cube cube = read_mat(dir / "img1.mat", "", std::string("lbl"), WavelengthGrid(kNm));
    expect_cube(cube, 0.5);
    EXPECT_FALSE(cube.valid(2, 1));
    EXPECT_TRUE(cube.valid(1, 2));
  }
}

TEST(MatLayouts, IcvlRadBandsV73AndAradCubeBandsFirst) {
  ScratchDir dir;
  // ICVL: rad rows x cols x bands with `bands` in nm, v7.3.
  if (!write_mat(dir / "icvl.mat", MAT_FT_MAT73,
                 {make_var("rad", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols, kBands}, column_major<double>()),
                  make_var("bands", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, 1}, kNm)}))
    GTEST_SKIP() << "no v7.3 support in this matio";
  Cube cube = read_mat(dir / "icvl.mat", "", std::nullopt, {});
  expect_cube(cube);
  EXPECT_EQ(cube.wavelengths[3], 550.0);
  // ARAD-1K as seen through HDF5: cube bands x rows x cols, single, `bands` a row vector.
  ASSERT_TRUE(write_mat(dir / "arad.mat", MAT_FT_MAT73,
                        {make_var("cube", MAT_C_SINGLE, MAT_T_SINGLE, {kBands, kRows, kCols}, bands_first()),
                         make_var("bands", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, kNm)}));
  {
    mat_t* m = Mat_Open((dir / "arad.mat").c_str(), MAT_ACC_RDONLY);
    ASSERT_NE(m, nullptr);
    matvar_t* v = Mat_VarReadInfo(m, "cube");
    ASSERT_NE(v, nullptr);
    EXPECT_EQ(v->dims[0], kBands);  // matio reports the dims as written (it undoes HDF5's reversal)
    EXPECT_EQ(v->dims[2], kCols);
    Mat_VarFree(v);
    Mat_Close(m);
  }
  cube = read_mat(dir / "arad.mat", "", std::nullopt, {});
  expect_cube(cube);
  EXPECT_EQ(cube.wavelengths[0], 400.0);
  // The same bands-first cube in a v5 file, named explicitly, wavelengths in micrometres as `Lambda`.
  const std::vector<double> um = {0.4, 0.45, 0.5, 0.55, 0.6};
  ASSERT_TRUE(write_mat(dir / "um.mat", MAT_FT_MAT5,
                        {make_var("x", MAT_C_SINGLE, MAT_T_SINGLE, {kBands, kRows, kCols}, bands_first()),
                         make_var("Lambda", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, um)}));
  cube = read_mat(dir / "um.mat", "x", std::nullopt, {});
  expect_cube(cube);
  EXPECT_NEAR(cube.wavelengths[1], 450.0, 1e-9);
}

TEST(MatLayouts, FosterReflectancesNeedTheOption) {
  ScratchDir dir;
  ASSERT_TRUE(write_mat(
      dir / "foster.mat", MAT_FT_MAT5,
      {make_var("reflectances", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols, kBands}, column_major<double>())}));
  const std::string m = test::error_of([&] { read_mat(dir / "foster.mat", "", std::nullopt, {}); });
  EXPECT_EQ(m, (dir / "foster.mat").string() +
                   ": no wavelength variable (wavelength, wavelengths, bands, wl or lambda) for the 5 bands of "
                   "'reflectances'; give the `wavelengths` option FIRST:LAST:STEP");
  const Cube cube = read_mat(dir / "foster.mat", "", std::nullopt, WavelengthGrid::range(410, 450, 10));
  expect_cube(cube);
  EXPECT_EQ(cube.wavelengths[4], 450.0);
}

TEST(MatLayouts, IndianPinesUnknownNameAndAmbiguity) {
  ScratchDir dir;
  ASSERT_TRUE(write_mat(dir / "Indian_pines_corrected.mat", MAT_FT_MAT5,
                        {make_var("indian_pines_corrected", MAT_C_UINT16, MAT_T_UINT16, {kRows, kCols, kBands},
                                  column_major<std::uint16_t>(1000))}));
  const std::string m = test::error_of([&] { read_mat(dir / "Indian_pines_corrected.mat", "", std::nullopt, {}); });
  EXPECT_EQ(std::count(m.begin(), m.end(), '\n'), 0);
  EXPECT_NE(m.find("bands of 'indian_pines_corrected'; give the `wavelengths` option"), std::string::npos) << m;
  expect_cube(read_mat(dir / "Indian_pines_corrected.mat", "", std::nullopt, WavelengthGrid(kNm)), 1000);

  ASSERT_TRUE(write_mat(dir / "two.mat", MAT_FT_MAT5,
                        {make_var("a", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols, kBands}, column_major<double>()),
                         make_var("b", MAT_C_DOUBLE, MAT_T_DOUBLE, {kRows, kCols, kBands}, column_major<double>())}));
  const std::string amb = test::error_of([&] { read_mat(dir / "two.mat", "", std::nullopt, WavelengthGrid(kNm)); });
  EXPECT_NE(amb.find("several 3-D variables (a, b)"), std::string::npos) << amb;
  EXPECT_NE(amb.find("give its name as the `var` option"), std::string::npos) << amb;
  expect_cube(read_mat(dir / "two.mat", "b", std::nullopt, WavelengthGrid(kNm)));
}

TEST(MatLayouts, JasperRidgeYWithNRowNColColumnMajorPixels) {
  // Y is bands x pixels, pixel p = r + nRow * c; also pixels x bands; and SlectBands picks from a full grid.
  std::vector<double> bp(kBands * kRows * kCols), pb(kBands * kRows * kCols);
  const std::size_t px = kRows * kCols;
  for (std::size_t r = 0; r < kRows; ++r)
    for (std::size_t c = 0; c < kCols; ++c)
      for (std::size_t b = 0; b < kBands; ++b) {
        bp[b + kBands * (r + kRows * c)] = f(r, c, b);
        pb[(r + kRows * c) + px * b] = f(r, c, b);
      }
  const std::vector<double> nrow = {double(kRows)}, ncol = {double(kCols)};
  const std::vector<double> kept = {2, 3, 5, 8, 9};  // 1-based into a 10-band grid 400:490:10
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    ScratchDir dir;
    if (!write_mat(dir / "jasper.mat", version,
                   {make_var("Y", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, px}, bp),
                    make_var("nRow", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, nrow),
                    make_var("nCol", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, ncol),
                    make_var("SlectBands", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, 1}, kept)}))
      GTEST_SKIP() << "no v7.3 support in this matio";
    EXPECT_EQ(mat_kind(dir / "jasper.mat"), MatKind::image);
    Cube cube = read_mat(dir / "jasper.mat", "", std::nullopt, WavelengthGrid(kNm));
    expect_cube(cube);
    cube = read_mat(dir / "jasper.mat", "", std::nullopt, WavelengthGrid::range(400, 490, 10));
    expect_cube(cube);
    EXPECT_EQ(cube.wavelengths[0], 410.0);
    EXPECT_EQ(cube.wavelengths[4], 480.0);
    ASSERT_TRUE(write_mat(dir / "urban.mat", version,
                          {make_var("A", MAT_C_DOUBLE, MAT_T_DOUBLE, {px, kBands}, pb),
                           make_var("nRow", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, nrow),
                           make_var("nCol", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, ncol)}));
    expect_cube(read_mat(dir / "urban.mat", "", std::nullopt, WavelengthGrid(kNm)));
  }
}

TEST(MatLayouts, IsetcamLibraryIsACollection) {
  // wavelength N x 1 and data N x M (one spectrum per column); also M x N (rows) named explicitly.
  constexpr std::size_t kSpectra = 3;
  std::vector<double> cols(kBands * kSpectra), rows(kBands * kSpectra);
  for (std::size_t j = 0; j < kSpectra; ++j)
    for (std::size_t k = 0; k < kBands; ++k) {
      cols[k + kBands * j] = 0.1 * double(j) + 0.01 * double(k);
      rows[j + kSpectra * k] = 0.1 * double(j) + 0.01 * double(k);
    }
  for (mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    ScratchDir dir;
    if (!write_mat(dir / "lib.mat", version,
                   {make_var("wavelength", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, 1}, kNm),
                    make_var("data", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, kSpectra}, cols),
                    make_var("rowwise", MAT_C_DOUBLE, MAT_T_DOUBLE, {kSpectra, kBands}, rows)}))
      GTEST_SKIP() << "no v7.3 support in this matio";
    EXPECT_EQ(mat_kind(dir / "lib.mat"), MatKind::collection);
    EXPECT_EQ(mat_kind(dir / "lib.mat", "rowwise"), MatKind::collection);
    for (const char* var : {"", "rowwise"}) {
      SCOPED_TRACE(var);
      const Collection col = read_mat_collection(dir / "lib.mat", var, {});
      ASSERT_EQ(col.size(), kSpectra);
      ASSERT_EQ(col.bands(), kBands);
      EXPECT_EQ(col.wavelengths[2], 500.0);
      EXPECT_EQ(col.names[1], std::string(*var ? var : "data") + "_2");
      EXPECT_EQ(col.provenance.importer, "mat");
      for (std::size_t j = 0; j < kSpectra; ++j)
        for (std::size_t k = 0; k < kBands; ++k)
          EXPECT_EQ(col.values[j * kBands + k], static_cast<float>(0.1 * double(j) + 0.01 * double(k)))
              << j << "," << k;
    }
  }
}

// Issue 18: an unsorted wavelength variable is kept, the bands permuted with it; a wavelength listed twice is refused.
TEST(MatLayouts, UnsortedWavelengthsAreSortedWithTheirBands) {
  const std::vector<double> unsorted = {500, 400, 600, 450, 550};
  const std::size_t source[kBands] = {1, 3, 0, 4, 2};  // the file's band at 400, 450, 500, 550, 600 nm
  ScratchDir dir;
  ASSERT_TRUE(write_mat(dir / "cube.mat", MAT_FT_MAT5,
                        {make_var("wavelengths", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, unsorted), ref_double()}));
  const Cube cube = read_mat(dir / "cube.mat", "ref", std::nullopt, {});
  ASSERT_EQ(cube.bands, kBands);
  for (std::size_t k = 0; k < kBands; ++k) EXPECT_EQ(cube.wavelengths[k], kNm[k]);
  for (std::size_t r = 0; r < kRows; ++r)
    for (std::size_t c = 0; c < kCols; ++c)
      for (std::size_t k = 0; k < kBands; ++k)
        EXPECT_EQ(cube.pixel(r, c)[k], static_cast<float>(f(r, c, source[k]) + 0.5)) << r << "," << c << "," << k;

  constexpr std::size_t kSpectra = 2;
  std::vector<double> library(kBands * kSpectra);  // one spectrum per column, in the file's band order
  for (std::size_t j = 0; j < kSpectra; ++j)
    for (std::size_t b = 0; b < kBands; ++b) library[b + kBands * j] = double(j) + 0.001 * unsorted[b];
  ASSERT_TRUE(write_mat(dir / "lib.mat", MAT_FT_MAT5,
                        {make_var("wavelength", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, 1}, unsorted),
                         make_var("data", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, kSpectra}, library)}));
  const Collection col = read_mat_collection(dir / "lib.mat", "", {});
  ASSERT_EQ(col.bands(), kBands);
  for (std::size_t k = 0; k < kBands; ++k) EXPECT_EQ(col.wavelengths[k], kNm[k]);
  for (std::size_t j = 0; j < kSpectra; ++j)
    for (std::size_t k = 0; k < kBands; ++k)
      EXPECT_EQ(col.values[j * kBands + k], static_cast<float>(library[source[k] + kBands * j])) << j << "," << k;

  ASSERT_TRUE(write_mat(
      dir / "twice.mat", MAT_FT_MAT5,
      {make_var("wavelengths", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, std::vector<double>{500, 400, 600, 400, 550}),
       ref_double()}));
  try {
    read_mat(dir / "twice.mat", "ref", std::nullopt, {});
    ADD_FAILURE() << "a wavelength listed twice was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(
        std::string(e.what()).find(
            "twice.mat: variable 'wavelengths' lists wavelength 400 nm twice (bands 2 and 4); remove one of them"),
        std::string::npos)
        << e.what();
  }
}

TEST(MatLayouts, WavelengthNamesAndUnitsRule) {
  ScratchDir dir;
  const std::vector<double> numbering = {1, 2, 3, 4, 5}, ints = {1, 2, 3, 4, 6};
  ASSERT_TRUE(write_mat(dir / "n.mat", MAT_FT_MAT5,
                        {ref_double(), make_var("bands", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, kBands}, numbering)}));
  std::string m = test::error_of([&] { read_mat(dir / "n.mat", "", std::nullopt, {}); });
  EXPECT_NE(m.find("variable 'bands' holds band numbers 1..5, not wavelengths; give the `wavelengths` option"),
            std::string::npos)
      << m;
  EXPECT_EQ(read_mat(dir / "n.mat", "", std::nullopt, WavelengthGrid(kNm)).wavelengths[4], 600.0);
  // `WL` matches case-insensitively; integers below 20 are not micrometres, they stay nm.
  ASSERT_TRUE(write_mat(dir / "i.mat", MAT_FT_MAT5,
                        {ref_double(), make_var("WL", MAT_C_DOUBLE, MAT_T_DOUBLE, {kBands, 1}, ints)}));
  const Cube cube = read_mat(dir / "i.mat", "", std::nullopt, {});
  expect_cube(cube, 0.5);
  EXPECT_EQ(cube.wavelengths[4], 6.0);
}

TEST(Mat, ACubeOfManyTransposeTilesLandsWhereMatlabPutIt) {
  // 150 x 21 x 3: several tiles of rows and of columns, the last ones partial.
  constexpr std::size_t R = 150, C = 21, B = 3;
  std::vector<double> v(R * C * B);
  for (std::size_t r = 0; r < R; ++r)
    for (std::size_t c = 0; c < C; ++c)
      for (std::size_t b = 0; b < B; ++b) v[r + R * (c + C * b)] = 1000.0 * r + 10.0 * c + b;
  ScratchDir dir;
  ASSERT_TRUE(write_mat(dir / "big.mat", MAT_FT_MAT5, {make_var("ref", MAT_C_DOUBLE, MAT_T_DOUBLE, {R, C, B}, v)}));
  const Cube cube = read_mat(dir / "big.mat", "", std::nullopt, WavelengthGrid::range(500, 520, 10));
  ASSERT_EQ(cube.height, R);
  ASSERT_EQ(cube.width, C);
  for (std::size_t r = 0; r < R; ++r)
    for (std::size_t c = 0; c < C; ++c)
      for (std::size_t b = 0; b < B; ++b)
        ASSERT_EQ(cube.pixel(r, c)[b], float(1000.0 * r + 10.0 * c + b)) << r << "," << c;
}

}  // namespace
}  // namespace specula::store
