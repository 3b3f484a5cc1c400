// The format-2 store as a shared database: concurrent writers lose nothing, a crash at any point of a commit leaves
// the store as before or after, readers keep one committed state while others replace and collect, conflicts fail
// cleanly, a write costs what it changes, and format-1 stores upgrade in place.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

#include "specula/store/block_reader.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;
namespace fs = std::filesystem;

namespace {

// A CSV collection of `rows` spectra on 400..700 nm step 10, every value `value`.
void write_csv(const fs::path& p, int rows, double value) {
  std::ofstream out(p);
  out << "name";
  for (int nm = 400; nm <= 700; nm += 10) out << ',' << nm;
  out << '\n';
  for (int r = 0; r < rows; ++r) {
    out << "s" << r;
    for (int nm = 400; nm <= 700; nm += 10) out << ',' << value;
    out << '\n';
  }
}

Collection constant_collection(std::size_t n, float value) {
  Collection c;
  for (std::size_t i = 0; i < n; ++i) c.names.push_back("s" + std::to_string(i));
  c.wavelengths = WavelengthGrid::range(400, 700, 10);
  c.values.assign(n * c.wavelengths.size(), value);
  return c;
}

// Every regular file under the data directory's objects/, relative to the data directory.
std::set<std::string> data_files(const fs::path& data) {
  std::set<std::string> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(data / "objects", ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
    if (it->is_regular_file()) out.insert(fs::relative(it->path(), data).string());
  return out;
}

std::set<std::string> referenced(const Store& s) {
  std::set<std::string> out;
  for (const auto& e : s.index().entries) out.insert(e.file);
  return out;
}

std::size_t count_entries(const fs::path& dir) {
  std::size_t n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) ++n;
  return n;
}

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

}  // namespace

TEST(StoreLayout, ConcurrentWritersLoseNothing) {
  test::ScratchDir dir;
  constexpr int kWriters = 8, kCommits = 20;
  for (int w = 0; w < kWriters; ++w)
    for (int i = 0; i < kCommits; ++i)
      write_csv(dir / ("w" + std::to_string(w) + "-" + std::to_string(i) + ".csv"), 3, w + i);
  // Each writer a shell loop of separate `specula import` processes, all eight loops at once.
  std::string script;
  for (int w = 0; w < kWriters; ++w) {
    script += "( for i in $(seq 0 " + std::to_string(kCommits - 1) + "); do '" SPECULA_BINARY "' -q import " +
              q(dir.path()) + "/w" + std::to_string(w) + "-$i.csv -o " + q(dir / "db.h5") +
              " >/dev/null || echo FAILED; done ) & ";
  }
  script += "wait\n";
  std::ofstream(dir / "writers.sh") << script;
  const auto r = test::run_shell("bash " + q(dir / "writers.sh"));
  EXPECT_EQ(r.status, 0);
  EXPECT_EQ(r.output.find("FAILED"), std::string::npos) << r.output;
  const Store s = Store::open(dir / "db.h5");
  EXPECT_EQ(s.collections().size(), std::size_t(kWriters * kCommits));
  EXPECT_EQ(s.index().generation, kWriters * kCommits);
  for (int w = 0; w < kWriters; ++w)
    for (int i = 0; i < kCommits; ++i) {
      const Collection c = s.read_collection("w" + std::to_string(w) + "-" + std::to_string(i));
      ASSERT_EQ(c.values.size(), 3u * 31u);
      EXPECT_EQ(c.values[40], float(w + i));
    }
  EXPECT_TRUE(check(dir / "db.h5").empty());
  EXPECT_EQ(data_files(s.data_dir()), referenced(s));
  EXPECT_EQ(count_entries(s.data_dir() / "tx"), 0u) << "a transaction's lock file was left behind";
}

TEST(StoreLayout, KillNineAtEveryPointOfACommitLeavesBeforeOrAfter) {
  const char* points[] = {"object-created", "data-written", "locked",   "garbage-logged",
                          "root-written",   "renamed",      "collected"};
  for (const char* point : points) {
    SCOPED_TRACE(point);
    test::ScratchDir dir;
    const fs::path db = dir / "db.h5";
    write_csv(dir / "base.csv", 2, 1.0);
    write_csv(dir / "victim.csv", 2, 2.0);
    ASSERT_EQ(
        test::run_specula("-q import " + q(dir / "base.csv") + " " + q(dir / "victim.csv") + " -o " + q(db)).status, 0);
    const std::string root_before = test::read_bytes(db);
    // The killed transaction replaces `victim` (so it has garbage to log) and adds `fresh`.
    write_csv(dir / "fresh.csv", 2, 3.0);
    fs::rename(dir / "victim.csv", dir / "victim-old.csv");
    write_csv(dir / "victim.csv", 2, 4.0);
    const auto r = test::run_shell(std::string("SPECULA_TEST_CRASH_AT=") + point + " '" SPECULA_BINARY "' -q import " +
                                   q(dir / "fresh.csv") + " " + q(dir / "victim.csv") + " --replace -o " + q(db));
    EXPECT_EQ(r.status, 128 + 9) << r.output;
    const bool after = std::string(point) == "renamed" || std::string(point) == "collected";
    {
      const Store s = Store::open(db);
      if (after) {
        EXPECT_EQ(s.collections(), (std::vector<std::string>{"base", "fresh", "victim"}));
        EXPECT_EQ(s.read_collection("victim").values[0], 4.0f);
      } else {
        EXPECT_EQ(test::read_bytes(db), root_before) << "the root changed before the commit point";
        EXPECT_EQ(s.collections(), (std::vector<std::string>{"base", "victim"}));
        EXPECT_EQ(s.read_collection("victim").values[0], 2.0f);
      }
      EXPECT_TRUE(check(db).empty());
    }
    const auto gc = test::run_specula("gc " + q(db));
    EXPECT_EQ(gc.status, 0) << gc.output;
    const Store s = Store::open(db);
    EXPECT_EQ(data_files(s.data_dir()), referenced(s)) << "gc left unreferenced data files";
    EXPECT_EQ(count_entries(s.data_dir() / "tx"), 0u);
    EXPECT_EQ(count_entries(dir.path()), 6u) << "a root temporary was left beside the store";  // db.h5, db.h5.d, 4 CSVs
    EXPECT_TRUE(check(db).empty());
    // The store takes the interrupted work again.
    EXPECT_EQ(test::run_specula("-q import " + q(dir / "fresh.csv") + " --replace -o " + q(db)).status, 0);
  }
}

TEST(StoreLayout, ReaderStreamingAnImageSeesTheOldOneWhileAnotherProcessReplacesAndCollects) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  ASSERT_EQ(test::run_specula("-q synth-db -o " + q(db) + " --images 1 --size 300x200 --seed 1 --prefix scene").status,
            0);
  const Store reader = Store::open(db);
  const Cube old_image = reader.read_image("scene0");
  BlockReader blocks(reader, {.image_globs = {"scene0"}}, 4096);
  ASSERT_GT(blocks.block_count(), 4u);
  std::vector<float> streamed;
  RowMatrixXf block;
  auto take = [&](std::size_t i) {
    blocks.read(i, block);
    streamed.insert(streamed.end(), block.data(), block.data() + block.size());
  };
  const std::size_t half = blocks.block_count() / 2;
  for (std::size_t i = 0; i < half; ++i) take(i);
  // Another process replaces the image, then collects garbage, while this reader is half-way.
  ASSERT_EQ(
      test::run_specula("-q synth-db -o " + q(db) + " --images 1 --size 300x200 --seed 2 --prefix scene --replace")
          .status,
      0);
  const auto gc = test::run_specula("gc " + q(db));
  ASSERT_EQ(gc.status, 0) << gc.output;
  EXPECT_NE(gc.output.find("1 still open by readers"), std::string::npos) << gc.output;
  for (std::size_t i = half; i < blocks.block_count(); ++i) take(i);
  std::vector<float> expected;
  for (std::size_t p = 0; p < old_image.height * old_image.width; ++p)
    if (old_image.valid(p / old_image.width, p % old_image.width))
      expected.insert(expected.end(), old_image.data.begin() + std::ptrdiff_t(p * old_image.bands),
                      old_image.data.begin() + std::ptrdiff_t((p + 1) * old_image.bands));
  EXPECT_TRUE(streamed == expected) << "the reader saw a mix of the old and the new image";
  // A reader opened now sees the new image; once the old reader is gone, gc reclaims the old file.
  const Cube new_image = Store::open(db).read_image("scene0");
  EXPECT_FALSE(new_image.data == old_image.data);
  const auto gc_again = test::run_specula("gc " + q(db));
  EXPECT_NE(gc_again.output.find("still open"), std::string::npos) << "the first reader is still open";
}

TEST(StoreLayout, OldFileIsReclaimedOnceNoReaderHoldsItsGeneration) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  {
    StoreWriter w(db, {});
    w.add_collection("c", constant_collection(4, 1.0f));
    w.commit();
  }
  std::optional<Store> reader = Store::open(db);
  {
    StoreWriter w(db, {.replace = true});
    w.add_collection("c", constant_collection(4, 2.0f));
    w.commit();
    EXPECT_EQ(w.reclaimed().in_use, 1u);
  }
  EXPECT_EQ(reader->read_collection("c").values[0], 1.0f);
  EXPECT_EQ(data_files(reader->data_dir()).size(), 2u);
  const fs::path data = reader->data_dir();
  reader.reset();
  const auto r = collect_garbage(db);
  EXPECT_EQ(r.files, 1u);
  EXPECT_EQ(data_files(data).size(), 1u);
  EXPECT_EQ(Store::open(db).read_collection("c").values[0], 2.0f);
}

TEST(StoreLayout, ConflictingNameFailsAndLeavesNothingBehind) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  {
    StoreWriter w(db, {});
    w.add_collection("base", constant_collection(2, 1.0f));
    w.commit();
  }
  const fs::path data = Store::open(db).data_dir();
  std::string root;
  {
    StoreWriter first(db, {}), second(db, {});
    first.add_collection("x", constant_collection(2, 2.0f));
    second.add_collection("x", constant_collection(2, 3.0f));
    second.add_collection("y", constant_collection(2, 3.0f));
    first.commit();
    root = test::read_bytes(db);
    const std::string err = test::input_error_text([&] { second.commit(); });
    EXPECT_NE(err.find("collections/x was committed by another writer"), std::string::npos) << err;
    EXPECT_EQ(test::read_bytes(db), root);
  }
  const Store s = Store::open(db);
  EXPECT_EQ(data_files(data), referenced(s)) << "the failed transaction left data files";
  EXPECT_EQ(s.collections(), (std::vector<std::string>{"base", "x"}));
  EXPECT_EQ(s.read_collection("x").values[0], 2.0f);
  // Through the CLI: one line, exit 1, and the store unchanged.
  write_csv(dir / "x.csv", 2, 9.0);
  const auto r = test::run_specula("-q import " + q(dir / "x.csv") + " -o " + q(db));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_NE(r.output.find("exists already"), std::string::npos) << r.output;
  EXPECT_EQ(test::read_bytes(db), root);
}

TEST(StoreLayout, WriteCostsWhatItChangesNotTheStoresSize) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  ASSERT_EQ(test::run_specula("-q synth-db -o " + q(db) + " --images 6 --size 400x300 --compression none").status, 0);
  const Store before = Store::open(db);
  const std::uint64_t store_size = store_bytes(before);
  ASSERT_GT(store_size, 80u << 20);
  const auto files_before = data_files(before.data_dir());
  {
    StoreWriter w(db, {});
    w.add_collection("small", constant_collection(10, 0.5f));
    w.commit();
  }
  const Store after = Store::open(db);
  std::uint64_t written = fs::file_size(db);
  for (const auto& f : data_files(after.data_dir()))
    if (!files_before.count(f)) written += fs::file_size(after.data_dir() / f);
  EXPECT_LT(written, 64u << 10) << "a 10-spectrum collection cost " << written << " bytes in a " << store_size
                                << "-byte store";
  for (const auto& f : files_before) EXPECT_TRUE(data_files(after.data_dir()).count(f)) << f << " was rewritten";
}

TEST(StoreLayout, FormatOneStoresAreReadOnlyAndUpgradeInPlace) {
  test::ScratchDir dir;
  const fs::path db = dir / "v1.h5";
  fs::copy_file(SPECULA_SOURCE_DIR "/tests/store/data/v1-store.h5", db);
  const std::string v1_bytes = test::read_bytes(db);
  const Store v1 = Store::open(db);
  ASSERT_EQ(v1.format_version(), 1);
  const Cube image = v1.read_image("synth0");
  const Collection col = v1.read_collection("m");
  const Basis basis = v1.read_basis("pca");
  const Grid grid = v1.read_grid("gm");
  std::vector<double> angles(200 * 4);
  std::vector<float> values(200 * 6);
  v1.read_samples("rp", 0, 200, angles, values);
  // Writing says how to convert it.
  const std::string err = test::input_error_text([&] { StoreWriter w(db, {}); });
  EXPECT_NE(err.find("specula upgrade"), std::string::npos) << err;
  // A crash before the commit point leaves the format-1 file as it was.
  const auto killed =
      test::run_shell("SPECULA_TEST_CRASH_AT=upgrade-root-written '" SPECULA_BINARY "' upgrade " + q(db));
  EXPECT_EQ(killed.status, 128 + 9);
  EXPECT_EQ(test::read_bytes(db), v1_bytes);
  const auto up = test::run_specula("upgrade " + q(db));
  ASSERT_EQ(up.status, 0) << up.output;
  const Store v2 = Store::open(db);
  EXPECT_EQ(v2.format_version(), 2);
  EXPECT_EQ(v2.index().entries.size(), 7u);
  EXPECT_TRUE(v2.read_image("synth0").data == image.data);
  EXPECT_TRUE(v2.read_image("synth0").mask == image.mask);
  EXPECT_TRUE(v2.read_collection("m").values == col.values);
  EXPECT_TRUE(v2.read_basis("pca").components == basis.components);
  EXPECT_TRUE(v2.read_grid("gm").brdf == grid.brdf);
  std::vector<double> angles2(200 * 4);
  std::vector<float> values2(200 * 6);
  v2.read_samples("rp", 0, 200, angles2, values2);
  EXPECT_TRUE(angles2 == angles && values2 == values);
  EXPECT_EQ(v2.coefficients_info("synth0.pca").k, 3u);
  EXPECT_TRUE(check(db).empty());
  // The legacy data file is the format-1 file itself, not a copy.
  EXPECT_EQ(test::read_bytes(v2.data_dir() / v2.index().entries.front().file), v1_bytes);
  // Writing works now, and the upgrade refuses to run twice.
  {
    StoreWriter w(db, {});
    w.add_collection("new", constant_collection(2, 1.0f));
    w.commit();
  }
  EXPECT_EQ(Store::open(db).collections(), (std::vector<std::string>{"m", "new"}));
  EXPECT_NE(test::input_error_text([&] { upgrade(db); }).find("already store format version 2"), std::string::npos);
}

TEST(StoreLayout, CheckNamesCorruptTruncatedAndMissingDataFiles) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  {
    StoreWriter w(db, {});
    w.add_collection("a", constant_collection(50, 1.0f));
    w.add_collection("b", constant_collection(50, 1.0f));
    w.add_collection("c", constant_collection(50, 1.0f));
    w.commit();
  }
  const Store s = Store::open(db);
  auto file_of = [&](const std::string& name) { return s.data_dir() / s.index().find("collections", name)->file; };
  {  // flip one byte in the middle of a's data
    std::fstream f(file_of("a"), std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(fs::file_size(file_of("a")) / 2));
    char c = 0;
    f.read(&c, 1);
    f.seekp(std::streamoff(fs::file_size(file_of("a")) / 2));
    c = char(c ^ 0x40);
    f.write(&c, 1);
  }
  fs::resize_file(file_of("b"), fs::file_size(file_of("b")) - 100);
  fs::remove(file_of("c"));
  const auto problems = check(db);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_NE(problems[0].what.find("collections/a: data file"), std::string::npos);
  EXPECT_NE(problems[0].what.find("checksum"), std::string::npos);
  EXPECT_NE(problems[1].what.find("collections/b"), std::string::npos);
  EXPECT_NE(problems[1].what.find("bytes"), std::string::npos);
  EXPECT_NE(problems[2].what.find("collections/c"), std::string::npos);
  EXPECT_NE(problems[2].what.find("missing"), std::string::npos);
  const auto r = test::run_specula("check " + q(db));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("3 problem(s)"), std::string::npos) << r.output;
  // Reading the missing object says which file is gone instead of an HDF5 stack.
  const std::string err = test::input_error_text([&] { (void)Store::open(db).read_collection("c"); });
  EXPECT_NE(err.find("cannot be opened (missing or corrupt)"), std::string::npos) << err;
}

TEST(StoreLayout, RmRemovesObjectsAndGcReclaimsTheirFiles) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  write_csv(dir / "a.csv", 2, 1.0);
  write_csv(dir / "b.csv", 2, 1.0);
  ASSERT_EQ(test::run_specula("-q import " + q(dir / "a.csv") + " " + q(dir / "b.csv") + " -o " + q(db)).status, 0);
  auto r = test::run_specula("rm " + q(db) + " collections/a");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("reclaimed 1 file(s)"), std::string::npos) << r.output;
  const Store s = Store::open(db);
  EXPECT_EQ(s.collections(), (std::vector<std::string>{"b"}));
  EXPECT_EQ(data_files(s.data_dir()), referenced(s));
  r = test::run_specula("rm " + q(db) + " nothing");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("no object 'nothing'"), std::string::npos) << r.output;
  r = test::run_specula("rm " + q(db) + " widgets/b");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("'widgets' is not a kind of object"), std::string::npos) << r.output;
  EXPECT_EQ(Store::open(db).collections(), (std::vector<std::string>{"b"}));
}

TEST(StoreLayout, ACopyOfTheRootAloneReadsButRefusesToWrite) {
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5", copy = dir / "copy.h5", moved = dir / "moved.h5";
  {
    StoreWriter w(db, {});
    w.add_collection("a", constant_collection(2, 1.0f));
    w.commit();
  }
  fs::copy_file(db, copy);
  EXPECT_EQ(Store::open(copy).read_collection("a").values[0], 1.0f);
  const std::string err = test::input_error_text([&] { StoreWriter w(copy, {}); });
  EXPECT_NE(err.find("copy.h5: its data directory db.h5.d belongs to db.h5"), std::string::npos) << err;
  EXPECT_NE(test::input_error_text([&] { collect_garbage(copy); }).find("belongs to db.h5"), std::string::npos);
  // Renaming the root alone is fine: the directory follows the store that remains.
  fs::remove(copy);
  fs::rename(db, moved);
  {
    StoreWriter w(moved, {});
    w.add_collection("b", constant_collection(2, 2.0f));
    w.commit();
  }
  EXPECT_EQ(Store::open(moved).collections(), (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(check(moved).empty());
}

TEST(StoreLayout, MalformedRootsAreOneLineErrors) {
  if (std::system("/usr/bin/python3 -c 'import h5py' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "Debian's python3-h5py is not installed (scripts/setup-deps installs it)";
  test::ScratchDir dir;
  const fs::path db = dir / "db.h5";
  {
    StoreWriter w(db, {});
    w.add_collection("a", constant_collection(2, 1.0f));
    w.commit();
  }
  const std::string good = test::read_bytes(db);
  struct Case {
    std::string python, expect;
  };
  const std::vector<Case> cases = {
      {"del f['index']; f['index'] = 'not json'", "/index is not a valid index"},
      {"f.attrs['data_dir'] = '../elsewhere'", "is not a directory name"},
      {"import json; j = json.loads(f['index'][()]); j['objects'][0]['file'] = '../../etc/passwd'; "
       "del f['index']; f['index'] = json.dumps(j)",
       "index entry 'collections/a' is malformed"},
      {"f.attrs['format_version'] = 3", "store format version 3 is newer than this specula"},
  };
  for (const Case& c : cases) {
    std::ofstream(db, std::ios::binary | std::ios::trunc) << good;
    const std::string cmd =
        "/usr/bin/python3 -c \"import h5py\nwith h5py.File('" + db.string() + "', 'r+') as f:\n    " + c.python + "\"";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << c.python;
    const std::string err = test::input_error_text([&] { (void)Store::open(db); });
    EXPECT_NE(err.find("db.h5: "), std::string::npos) << err;
    EXPECT_NE(err.find(c.expect), std::string::npos) << c.python << ": " << err;
    const auto r = test::run_specula("ls " + q(db));
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
}
