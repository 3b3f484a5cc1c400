#include "specula/store/io/csv.h"

#include <fstream>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::store {
namespace {

using specula::test::write_file;

using test::ScratchDir;

std::string input_error(const std::filesystem::path& p, const WavelengthGrid& grid = {}) {
  try {
    read_csv_collection(p, grid);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected InputError for " << p;
  return {};
}

float at(const Collection& c, std::size_t spectrum, std::size_t band) { return c.values[spectrum * c.bands() + band]; }

TEST(Csv, HeaderRowWithNamesAndQuotes) {
  ScratchDir dir;
  write_file(dir / "a.csv",
             "\xEF\xBB\xBFname,400,500,600\r\nA,0.1,0.2,0.3\r\n\r\n\"B, \"\"quoted\"\"\", 1 ,2e-1,+3\r\n");
  const Collection c = read_csv_collection(dir / "a.csv");
  ASSERT_EQ(c.size(), 2u);
  ASSERT_EQ(c.bands(), 3u);
  EXPECT_EQ(c.names[0], "A");
  EXPECT_EQ(c.names[1], "B, \"quoted\"");
  EXPECT_EQ(c.wavelengths[0], 400.0);
  EXPECT_EQ(c.wavelengths[2], 600.0);
  EXPECT_EQ(at(c, 0, 1), 0.2f);
  EXPECT_EQ(at(c, 1, 0), 1.0f);
  EXPECT_EQ(at(c, 1, 1), 0.2f);
  EXPECT_EQ(at(c, 1, 2), 3.0f);
  EXPECT_EQ(c.provenance.importer, "csv");
}

TEST(Csv, HeaderRowWithoutNameColumn) {
  ScratchDir dir;
  write_file(dir / "n.csv", "450,550\n0.5,0.25\n0.75,1\n");
  const Collection c = read_csv_collection(dir / "n.csv");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.names[0], "spectrum_1");
  EXPECT_EQ(c.names[1], "spectrum_2");
  EXPECT_EQ(at(c, 1, 0), 0.75f);
  EXPECT_EQ(c.wavelengths[1], 550.0);
}

TEST(Csv, HeaderlessRowsTakeGivenWavelengths) {
  ScratchDir dir;
  write_file(dir / "h.csv", "red,0.1,0.2,0.9\ngrey,0.5,0.5,0.5\n");
  const Collection c = read_csv_collection(dir / "h.csv", WavelengthGrid({450, 550, 650}));
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.names[1], "grey");
  EXPECT_EQ(at(c, 0, 2), 0.9f);
  EXPECT_EQ(c.wavelengths[0], 450.0);
  const std::string msg = input_error(dir / "h.csv");
  EXPECT_NE(msg.find("h.csv:1:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("`wavelengths` option"), std::string::npos) << msg;
  write_file(dir / "hw.csv", "name,400,500\nA,0.1,0.2\n");
  const std::string differ = input_error(dir / "hw.csv", WavelengthGrid({450, 550, 650}));
  EXPECT_NE(differ.find("hw.csv:1: the header row lists 2 wavelengths 400-500 nm but the `wavelengths` option gives 3"),
            std::string::npos)
      << differ;
}

TEST(Csv, TransposedLayout) {
  ScratchDir dir;
  write_file(dir / "t.csv", "wavelength_nm,\"dark skin\",light\n400,0.1,0.2\n410,0.3,0.4\n420,0.5,0.6\n");
  const Collection c = read_csv_collection(dir / "t.csv");
  ASSERT_EQ(c.size(), 2u);
  ASSERT_EQ(c.bands(), 3u);
  EXPECT_EQ(c.names[0], "dark skin");
  EXPECT_EQ(c.names[1], "light");
  EXPECT_EQ(at(c, 0, 0), 0.1f);
  EXPECT_EQ(at(c, 0, 2), 0.5f);
  EXPECT_EQ(at(c, 1, 1), 0.4f);
  EXPECT_EQ(c.wavelengths[2], 420.0);
}

// Issue 18: an unsorted band list is kept, its values permuted with it; a wavelength listed twice is refused.
TEST(Csv, UnsortedWavelengthsAreSortedWithTheirValues) {
  ScratchDir dir;
  write_file(dir / "rows.csv", "name,600,400,500\nA,0.6,0.4,0.5\nB,6,4,5\n");
  const Collection r = read_csv_collection(dir / "rows.csv");
  ASSERT_EQ(r.bands(), 3u);
  EXPECT_EQ(std::vector<double>(r.wavelengths.values().begin(), r.wavelengths.values().end()),
            (std::vector<double>{400, 500, 600}));
  EXPECT_EQ(r.values, (std::vector<float>{0.4f, 0.5f, 0.6f, 4, 5, 6}));

  write_file(dir / "columns.csv", "wavelength,A,B\n410,0.41,4.1\n400,0.40,4.0\n420,0.42,4.2\n");
  const Collection c = read_csv_collection(dir / "columns.csv");
  ASSERT_EQ(c.bands(), 3u);
  EXPECT_EQ(std::vector<double>(c.wavelengths.values().begin(), c.wavelengths.values().end()),
            (std::vector<double>{400, 410, 420}));
  EXPECT_EQ(c.values, (std::vector<float>{0.40f, 0.41f, 0.42f, 4.0f, 4.1f, 4.2f}));

  write_file(dir / "twice.csv", "wavelength,A\n410,1\n400,2\n410,3\n");
  const std::string m = input_error(dir / "twice.csv");
  EXPECT_NE(m.find("twice.csv:4:1: wavelength 410 appears twice (also at line 2, column 1)"), std::string::npos) << m;
}

TEST(Csv, RoundTripIsExact) {
  Collection c;
  c.names = {"plain", "with, comma", "with \"quote\"", " padded ", "#hash"};
  c.wavelengths = WavelengthGrid({400.5, 401.25, 700});
  const float vals[] = {0.1f, 1.0f / 3.0f, 1e-7f,       -2.5f,  123456.789f, 0.3f,  7.0f,    8.0f,
                        9.0f, 3.14159265f, 2.0f / 7.0f, 1e-30f, 0.0f,        -0.0f, 65504.0f};
  c.values.assign(std::begin(vals), std::end(vals));
  ScratchDir dir;
  write_csv_collection(dir / "rt.csv", c);
  const std::string text = test::read_bytes(dir / "rt.csv");
  EXPECT_TRUE(text.starts_with("name,400.5,401.25,700\nplain,0.1,")) << text;
  const Collection r = read_csv_collection(dir / "rt.csv");
  EXPECT_EQ(r.names, c.names);
  EXPECT_EQ(r.values, c.values);
  EXPECT_TRUE(r.wavelengths.approx_equal(c.wavelengths, 0));
}

TEST(Csv, WriteRejectsMisuse) {
  Collection c;
  c.names = {"a"};
  c.wavelengths = WavelengthGrid({400, 500});
  c.values = {1.0f};
  ScratchDir dir;
  EXPECT_THROW(write_csv_collection(dir / "x.csv", c), UsageError);
  c.values = {1.0f, std::numeric_limits<float>::quiet_NaN()};
  EXPECT_THROW(write_csv_collection(dir / "x.csv", c), UsageError);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.csv"));
}

TEST(Csv, BadCellsNameLineAndColumn) {
  ScratchDir dir;
  write_file(dir / "nan.csv", "name,400,500,600\nA,0.1,0.2,0.3\nB,0.1,0.2,NaN\n");
  std::string m = input_error(dir / "nan.csv");
  EXPECT_NE(m.find("nan.csv:3:4: 'NaN' is not a finite number"), std::string::npos) << m;

  write_file(dir / "txt.csv", "name,400,500,600\nA,0.1,abc,0.3\n");
  m = input_error(dir / "txt.csv");
  EXPECT_NE(m.find("txt.csv:2:3: 'abc' is not a number"), std::string::npos) << m;

  write_file(dir / "rag.csv", "name,400,500,600\nA,0.1,0.2,0.3\n\nB,0.1,0.2\n");
  m = input_error(dir / "rag.csv");
  EXPECT_NE(m.find("rag.csv:4:4: row has 3 cells but the header on line 1 has 4"), std::string::npos) << m;

  write_file(dir / "long.csv", "name,400,500\nA,0.1,0.2,0.3\n");
  m = input_error(dir / "long.csv");
  EXPECT_NE(m.find("long.csv:2:4: row has 4 cells"), std::string::npos) << m;

  write_file(dir / "empty.csv", "name,400,500\nA,,0.2\n");
  m = input_error(dir / "empty.csv");
  EXPECT_NE(m.find("empty.csv:2:2: empty cell"), std::string::npos) << m;

  write_file(dir / "order.csv", "name,400,500,400\nA,0.1,0.2,0.3\n");
  m = input_error(dir / "order.csv");
  EXPECT_NE(m.find("order.csv:1:4: wavelength 400 appears twice (also at line 1, column 2); remove one of them"),
            std::string::npos)
      << m;

  write_file(dir / "tnan.csv", "wavelength,a,b\n400,0.1,0.2\n410,inf,0.2\n");
  m = input_error(dir / "tnan.csv");
  EXPECT_NE(m.find("tnan.csv:3:2: 'inf' is not a finite number"), std::string::npos) << m;

  write_file(dir / "quote.csv", "name,400\n\"A,0.1\n");
  m = input_error(dir / "quote.csv");
  EXPECT_NE(m.find("quote.csv:2:1: the quote is never closed"), std::string::npos) << m;

  write_file(dir / "blank.csv", "\n\n");
  m = input_error(dir / "blank.csv");
  EXPECT_NE(m.find("blank.csv: no rows"), std::string::npos) << m;
  for (const auto* f : {"nan.csv", "txt.csv", "rag.csv", "order.csv", "quote.csv"})
    EXPECT_EQ(input_error(dir / f).find('\n'), std::string::npos) << f;
}

TEST(Csv, MunsellMattImports) {
  SPECULA_REQUIRE_SHARED();
  const Collection c = read_csv_collection(test::shared_dir() / "data/reflectance/munsell_matt_1269_380-780_5nm.csv");
  ASSERT_EQ(c.size(), 1269u);
  ASSERT_EQ(c.bands(), 81u);
  EXPECT_EQ(c.wavelengths.front(), 380.0);
  EXPECT_EQ(c.wavelengths.back(), 780.0);
  EXPECT_TRUE(c.wavelengths.uniform());
  EXPECT_EQ(c.names[0], "2.5R9/2");
  EXPECT_EQ(at(c, 0, 0), 0.13734f);
  EXPECT_EQ(at(c, 0, 40), 0.76372f);  // 580 nm
  EXPECT_EQ(at(c, 0, 80), 0.75638f);
  EXPECT_EQ(c.names[498], "10GY8/1");
  EXPECT_EQ(at(c, 498, 0), 0.12852f);
  EXPECT_EQ(at(c, 498, 40), 0.49762f);
  EXPECT_EQ(c.names[1268], "10RP4/12");
  EXPECT_EQ(at(c, 1268, 0), 0.08006f);
  EXPECT_EQ(at(c, 1268, 80), 0.68514f);
}

TEST(Csv, ColorCheckerTransposedImports) {
  SPECULA_REQUIRE_SHARED();
  const Collection c =
      read_csv_collection(test::shared_dir() / "data/reflectance/colorchecker24_ohta1997_reflectance.csv");
  ASSERT_EQ(c.size(), 24u);
  ASSERT_EQ(c.bands(), 81u);
  EXPECT_EQ(c.wavelengths.front(), 380.0);
  EXPECT_EQ(c.wavelengths.back(), 780.0);
  EXPECT_EQ(c.names[0], "dark skin");
  EXPECT_EQ(c.names[2], "blue sky");
  EXPECT_EQ(c.names[18], "white 9.5 (.05 D)");
  EXPECT_EQ(c.names[23], "black 2 (1.5 D)");
  EXPECT_EQ(at(c, 0, 0), 0.048f);
  EXPECT_EQ(at(c, 0, 40), 0.115f);  // 580 nm
  EXPECT_EQ(at(c, 2, 40), 0.163f);
  EXPECT_EQ(at(c, 18, 40), 0.887f);
  EXPECT_EQ(at(c, 18, 80), 0.879f);
  EXPECT_EQ(at(c, 23, 80), 0.032f);
}

}  // namespace
}  // namespace specula::store
