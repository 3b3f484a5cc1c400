// `specula pca` and `specula nmf` over a database split into several store files: the same answer as one
// store holding the same images in the same order, and clear errors for the misuses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

// a.h5 (2 images) and b.h5 (1 image), and all.h5 holding the same three images in the order a, then b.
void make_split_database(const test::ScratchDir& dir) {
  ASSERT_EQ(run_specula("-q synth-db -o '" + (dir / "a.h5").string() + "' --images 2 --size 70x90 --seed 1").status, 0);
  ASSERT_EQ(run_specula("-q synth-db -o '" + (dir / "b.h5").string() + "' --images 1 --size 70x90 --seed 2").status, 0);
  store::StoreWriter w(dir / "all.h5", {});
  const char* prefix[] = {"a", "b"};
  int file = 0;
  for (const char* f : {"a.h5", "b.h5"}) {
    const store::Store s = store::Store::open(dir / f);
    for (const auto& name : s.images()) w.add_image(std::string(prefix[file]) + "_" + name, s.read_image(name));
    ++file;
  }
  w.commit();
}

}  // namespace

TEST(MultiStore, PcaOfSeveralStoresEqualsPcaOfOneStoreWithTheirImages) {
  test::ScratchDir dir;
  make_split_database(dir);
  const auto out = dir / "bases.h5";
  auto r = run_specula("-q pca '" + (dir / "a.h5").string() + "' '" + (dir / "b.h5").string() + "' -o '" +
                       out.string() + "' --name split");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_specula("-q pca '" + (dir / "all.h5").string() + "' -o '" + out.string() + "' --name whole");
  ASSERT_EQ(r.status, 0) << r.output;
  const store::Store s = store::Store::open(out);
  const store::Basis split = s.read_basis("split"), whole = s.read_basis("whole");
  EXPECT_EQ(split.n, whole.n);
  EXPECT_LT((split.mean - whole.mean).norm(), 1e-12 * whole.mean.norm());
  EXPECT_LT((split.covariance - whole.covariance).norm(), 1e-12 * whole.covariance.norm());
  EXPECT_NE(split.provenance.source_file.find("b.h5"), std::string::npos) << split.provenance.source_file;
}

TEST(MultiStore, NmfOfSeveralStoresEqualsNmfOfOneStoreWithTheirImages) {
  test::ScratchDir dir;
  make_split_database(dir);
  const std::string common = " -k 3 --max-epochs 4 --tol 0 --json -o '" + (dir / "bases.h5").string() + "'";
  auto split =
      run_specula("-q nmf '" + (dir / "a.h5").string() + "' '" + (dir / "b.h5").string() + "' --name s" + common);
  ASSERT_EQ(split.status, 0) << split.output;
  auto whole = run_specula("-q nmf '" + (dir / "all.h5").string() + "' --name w" + common);
  ASSERT_EQ(whole.status, 0) << whole.output;
  EXPECT_EQ(test::json_number(split.output, "n"), test::json_number(whole.output, "n"));
  EXPECT_NEAR(test::json_number(split.output, "rel_error"), test::json_number(whole.output, "rel_error"),
              1e-12 * test::json_number(whole.output, "rel_error"));
  const store::Store s = store::Store::open(dir / "bases.h5");
  EXPECT_LT((s.read_basis("s").components - s.read_basis("w").components).norm(), 1e-12);
}

TEST(MultiStore, TheBasisGoesToTheFirstStoreAndAnotherGridIsAOneLineError) {
  test::ScratchDir dir;
  make_split_database(dir);
  const std::string a = "'" + (dir / "a.h5").string() + "'", b = "'" + (dir / "b.h5").string() + "'";
  // Several inputs and no -o: the basis goes into the first store, the others are not touched.
  const std::string b_before = test::read_bytes(dir / "b.h5");
  auto saved = run_specula("-q pca " + a + " " + b + " --name both");
  ASSERT_EQ(saved.status, 0) << saved.output;
  EXPECT_EQ(store::Store::open(dir / "a.h5").read_basis("both").n,
            store::Store::open(dir / "all.h5").image_info("a_synth0").valid_pixels +
                store::Store::open(dir / "all.h5").image_info("a_synth1").valid_pixels +
                store::Store::open(dir / "all.h5").image_info("b_synth0").valid_pixels);
  EXPECT_EQ(test::read_bytes(dir / "b.h5"), b_before);
  // A store on another wavelength grid.
  const auto odd = dir / "odd.h5";
  ASSERT_EQ(
      run_specula("-q synth-db -o '" + odd.string() + "' --images 1 --size 20x20 --wavelengths 400:700:20").status, 0);
  auto r = run_specula("-q pca " + a + " '" + odd.string() + "' -o '" + (dir / "x.h5").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("odd.h5"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.h5"));
}
