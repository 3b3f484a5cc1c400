// StateFileWriter/Reader: a round trip of every field kind, nothing at the path before commit, and one InputError
// naming the file for a foreign, newer, truncated or missing file.
#include "specula/store/state_file.h"

#include <gtest/gtest.h>

#include <fstream>

#include "specula/core/error.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;
using specula::test::ScratchDir;

namespace {

void expect_refused(const std::filesystem::path& p, long long version, const std::string& part) {
  try {
    StateFileReader(p, "test-state", version, "test state", "delete it");
    FAIL() << "read " << p;
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(p.string() + ": ", 0), 0u) << m;
    EXPECT_NE(m.find(part), std::string::npos) << m;
  }
}

}  // namespace

TEST(StateFile, RoundTripsEveryFieldAndAppearsOnlyOnCommit) {
  ScratchDir dir;
  const auto path = dir / "run.state";
  Eigen::MatrixXd m(2, 3);
  m << 1, 2, 3, 4.5, -5, 1e-300;
  const std::vector<double> v{0.25, -1, 3e12};
  {
    StateFileWriter w(path, "test-state", 3);
    w.attr("label", std::string_view("k=3 seed=7"));
    w.attr("count", 1234567890123LL);
    w.vector("history", v);
    w.matrix("basis", m);
    EXPECT_FALSE(std::filesystem::exists(path));
    w.commit();
  }
  const StateFileReader r(path, "test-state", 3, "test state", "delete it");
  EXPECT_EQ(r.string_attr("label"), "k=3 seed=7");
  EXPECT_EQ(r.int_attr("count"), 1234567890123LL);
  EXPECT_EQ(r.vector("history"), v);
  EXPECT_TRUE(r.matrix("basis") == m);
  EXPECT_THROW(r.matrix("absent"), InputError);

  {
    StateFileWriter abandoned(dir / "abandoned.state", "test-state", 3);
    abandoned.attr("count", 1LL);
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "abandoned.state"));
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename(), "run.state") << "a temporary was left behind";
}

TEST(StateFile, RefusesForeignNewerTruncatedAndMissingFiles) {
  ScratchDir dir;
  const auto path = dir / "run.state";
  {
    StateFileWriter w(path, "test-state", 3);
    w.attr("count", 1LL);
    w.commit();
  }
  expect_refused(path, 2, "test state format version 3, this specula reads version 2; delete it");
  {
    StateFileWriter w(dir / "other.state", "other-state", 3);
    w.commit();
  }
  expect_refused(dir / "other.state", 3, "not a specula test state");
  std::filesystem::copy_file(path, dir / "cut.state");
  std::filesystem::resize_file(dir / "cut.state", 100);
  expect_refused(dir / "cut.state", 3, "test state");
  std::ofstream(dir / "text.state") << "not hdf5";
  expect_refused(dir / "text.state", 3, "not an HDF5 file");
  expect_refused(dir / "missing.state", 3, "no such test state; delete it");
}
