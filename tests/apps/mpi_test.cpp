// `mpirun -np N specula pca|nmf`: the same answer as one process for N = 1, 2, 3, only rank 0 writes, and a
// failure on one rank stops every rank with its message and nothing written. Needs a SPECULA_MPI build.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "specula/store/h5.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

namespace {

// Loopback only, more ranks than cores allowed, one OpenMP thread per rank; root allowed (CI runs as root).
test::RunResult mpirun(int np, const std::string& args) {
  return test::run_shell(
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 '" + std::string(SPECULA_MPIEXEC) + "' -np " +
      std::to_string(np) +
      " --oversubscribe --bind-to none --mca btl self,vader --mca btl_vader_single_copy_mechanism none"
      " -x OMP_NUM_THREADS=1 '" +
      SPECULA_BINARY + "' " + args);
}

// Three 150x220 images: several blocks each, so every rank count splits the waves differently.
std::filesystem::path make_db(const test::ScratchDir& dir) {
  const auto db = dir / "db.h5";
  EXPECT_EQ(run_specula("-q synth-db -o '" + db.string() + "' --images 3 --size 150x220 --seed 7").status, 0);
  return db;
}

}  // namespace

TEST(Mpi, PcaOnOneTwoAndThreeRanksMatchesOneProcess) {
  test::ScratchDir dir;
  const auto db = make_db(dir);
  const auto out = dir / "bases.h5";
  auto r = run_specula("-q pca '" + db.string() + "' -o '" + out.string() + "' --name p0");
  ASSERT_EQ(r.status, 0) << r.output;
  for (int np : {1, 2, 3}) {
    const std::string name = "p" + std::to_string(np);
    r = mpirun(np, "-q pca '" + db.string() + "' -o '" + out.string() + "' --name " + name + " --json");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(test::json_number(r.output, "ranks"), np) << r.output;
    const store::Store s = store::Store::open(out);
    const store::Basis one = s.read_basis("p0"), many = s.read_basis(name);
    EXPECT_EQ(many.n, one.n);
    EXPECT_LT((many.mean - one.mean).norm(), 1e-12 * one.mean.norm()) << np;
    EXPECT_LT((many.covariance - one.covariance).norm(), 1e-12 * one.covariance.norm()) << np;
    EXPECT_LT((many.eigenvalues - one.eigenvalues).cwiseAbs().maxCoeff(), 1e-12 * one.eigenvalues[0]) << np;
  }
}

TEST(Mpi, NmfOnOneTwoAndThreeRanksMatchesOneProcess) {
  test::ScratchDir dir;
  const auto db = make_db(dir);
  const auto out = dir / "bases.h5";
  // Waves of 2 blocks: with 3 ranks some ranks hold no block of a wave.
  const std::string common =
      " -k 4 --max-epochs 4 --tol 0 --restarts 2 --wave-blocks 2 --json -o '" + out.string() + "'";
  auto one = run_specula("-q nmf '" + db.string() + "' --name n0" + common);
  ASSERT_EQ(one.status, 0) << one.output;
  for (int np : {1, 2, 3}) {
    const std::string name = "n" + std::to_string(np);
    auto r = mpirun(np, "-q nmf '" + db.string() + "' --name " + name + common);
    ASSERT_EQ(r.status, 0) << r.output;
    // One JSON line: only rank 0 reports.
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_NEAR(test::json_number(r.output, "rel_error"), test::json_number(one.output, "rel_error"),
                1e-12 * test::json_number(one.output, "rel_error"));
    const store::Store s = store::Store::open(out);
    const Eigen::MatrixXd a = s.read_basis("n0").components, b = s.read_basis(name).components;
    EXPECT_LT((a - b).norm(), 1e-12 * a.norm()) << np;
  }
}

TEST(Mpi, AFailureOnOneRankStopsEveryRankWithItsMessageAndWritesNothing) {
  test::ScratchDir dir;
  const auto db = make_db(dir);
  // A NaN in the last image, written past specula's own checks as a foreign tool could: only the last
  // rank's share holds it.
  {
    const hid_t f = H5Fopen(db.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hid_t d = H5Dopen2(f, "/images/synth2/cube", H5P_DEFAULT);
    const hid_t space = H5Dget_space(d);
    const hsize_t start[3] = {140, 10, 3}, count[3] = {1, 1, 1};
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    const hid_t mem = H5Screate_simple(3, count, nullptr);
    const float nan = std::nanf("");
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, mem, space, H5P_DEFAULT, &nan), 0);
    H5Sclose(mem);
    H5Sclose(space);
    H5Dclose(d);
    H5Fclose(f);
  }
  const std::string before = test::read_bytes(db);
  for (const char* cmd : {"pca", "nmf -k 3"}) {
    const auto out = dir / "out.h5";
    auto r = mpirun(2, std::string("-q ") + cmd + " '" + db.string() + "' -o '" + out.string() + "'");
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("rank 1 of 2: db.h5: image 'synth2'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("non-finite"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(out)) << cmd;
  }
  EXPECT_EQ(test::read_bytes(db), before);
}
