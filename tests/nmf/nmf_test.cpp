#include "specula/nmf/nmf.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <omp.h>

#include <random>

#include "specula/core/error.h"
#include "specula/core/interrupt.h"
#include "specula/nmf/checkpoint.h"
#include "specula/store/h5.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::nmf;
using specula::test::ScratchDir;

namespace {

constexpr int kBands = 16;

// k non-negative smooth spectra, each with one band where only it is non-zero (separable, so the
// factorisation is unique up to scale and order).
Eigen::MatrixXd planted_basis(int k) {
  Eigen::MatrixXd s(k, kBands);
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < kBands; ++j) {
      const double centre = 2.0 + 12.0 * i / std::max(1, k - 1);
      s(i, j) = std::exp(-0.5 * (j - centre) * (j - centre) / 9.0) + 0.05;
    }
  for (int i = 0; i < k; ++i)
    for (int l = 0; l < k; ++l)
      if (l != i) s(l, i * (kBands / k)) = 0.0;  // anchor band of component i
  for (int i = 0; i < k; ++i) s.row(i) /= s.row(i).norm();
  return s;
}

// N spectra C S (+ optional noise) as a collection in a new store.
std::filesystem::path make_store(const ScratchDir& dir, const Eigen::MatrixXd& s, std::size_t n, double noise,
                                 unsigned seed, const std::string& file = "db.h5") {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g;
  store::Collection col;
  col.wavelengths = WavelengthGrid::range(400, 400 + 10.0 * (kBands - 1), 10);
  col.units = "reflectance";
  col.values.resize(n * kBands);
  for (std::size_t i = 0; i < n; ++i) {
    col.names.push_back("s" + std::to_string(i));
    Eigen::VectorXd c(s.rows());
    for (Eigen::Index j = 0; j < c.size(); ++j) c[j] = u(rng) < 0.3 ? 0.0 : u(rng);  // sparse coefficients
    const Eigen::VectorXd x = s.transpose() * c;
    for (int b = 0; b < kBands; ++b) col.values[i * kBands + std::size_t(b)] = float(x[b] + noise * g(rng));
  }
  const auto path = dir / file;
  store::StoreWriter w(path, {});
  w.add_collection("c", col);
  w.commit();
  return path;
}

NmfResult run(const std::filesystem::path& path, NmfOptions o) {
  const store::Store s = store::Store::open(path);
  const store::BlockReader reader(s, {.collection = "c"}, 4096);
  return factorize(reader, o);
}

// The same run on `threads` OpenMP threads.
NmfResult run_on(int threads, const std::filesystem::path& path, const NmfOptions& o) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  NmfResult r = run(path, o);
  omp_set_num_threads(saved);
  return r;
}

}  // namespace

TEST(Nmf, RecoversAPlantedFactorisation) {
  ScratchDir dir;
  const Eigen::MatrixXd truth = planted_basis(4);
  const auto path = make_store(dir, truth, 20000, 0.0, 3);
  const NmfResult r = run(path, {.k = 4, .max_epochs = 3000, .tol = 0});
  const auto& best = r.best_result();
  // float32 storage of C S limits the attainable error to about 1e-7.
  EXPECT_LT(best.rel_error, 1e-6);
  const auto [mean_deg, max_deg] = basis_angles(best.basis, truth);
  EXPECT_LT(max_deg, 1e-4) << "mean " << mean_deg;
  EXPECT_LT(r.svd_bound, 1e-6);
  EXPECT_EQ(r.n, 20000u);
  EXPECT_GE(best.basis.minCoeff(), 0.0);
}

TEST(Nmf, CertifiedErrorNeverIncreasesAndStaysAboveTheSvdBound) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(6), 30000, 0.02, 4);
  const NmfResult r = run(path, {.k = 3, .init = Init::random, .seed = 9, .max_epochs = 40, .tol = 0});
  const auto& h = r.best_result().history;
  ASSERT_EQ(h.size(), 40u);
  for (std::size_t e = 1; e < h.size(); ++e) EXPECT_LE(h[e], h[e - 1] * (1 + 1e-12)) << "epoch " << e + 1;
  EXPECT_GT(h.front(), h.back() * 1.01);  // it did improve
  EXPECT_GE(r.best_result().rel_error, r.svd_bound);
  EXPECT_LE(r.rel_error, h.back());  // the certifying pass's exact coefficients do at least as well
  EXPECT_GE(r.rel_error, r.svd_bound);
  EXPECT_GT(r.svd_bound, 0.01);
}

TEST(Nmf, SameResultForOneAndTwoThreads) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(5), 30000, 0.01, 5);
  const NmfOptions o{.k = 5, .max_epochs = 8, .tol = 0};
  const NmfResult one = run_on(1, path, o);
  const NmfResult two = run_on(2, path, o);
  EXPECT_EQ(one.best_result().history, two.best_result().history);
  EXPECT_TRUE(one.best_result().basis == two.best_result().basis);
  EXPECT_TRUE(one.weights == two.weights);
}

TEST(Nmf, InterruptedRunResumesToTheUninterruptedResult) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(4), 20000, 0.01, 6);
  const NmfOptions plain{.k = 4, .restarts = 2, .max_epochs = 6, .tol = 0};
  const NmfResult straight = run(path, plain);

  NmfOptions o = plain;
  o.checkpoint = dir / "run.ckpt";
  o.on_epoch = [](const EpochReport& e) {
    if (e.restart == 1 && e.epoch == 2) request_interrupt();
  };
  EXPECT_THROW(run(path, o), Interrupted);
  clear_interrupt();
  const Checkpoint cp = load_checkpoint(o.checkpoint);
  EXPECT_EQ(cp.restart, 1u);
  EXPECT_EQ(cp.epoch, 2u);
  ASSERT_EQ(cp.done_bases.size(), 1u);

  o.on_epoch = nullptr;
  o.resume = true;
  const NmfResult resumed = run(path, o);
  EXPECT_TRUE(resumed.resumed);
  ASSERT_EQ(resumed.restarts.size(), 2u);
  for (std::size_t r = 0; r < 2; ++r) {
    EXPECT_EQ(resumed.restarts[r].history, straight.restarts[r].history) << "restart " << r;
    EXPECT_TRUE(resumed.restarts[r].basis == straight.restarts[r].basis);
  }
  EXPECT_EQ(resumed.best, straight.best);
}

TEST(Nmf, ResumeRefusesACheckpointOfAnotherRun) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(3), 5000, 0.01, 7);
  NmfOptions o{.k = 3, .max_epochs = 2, .tol = 0, .checkpoint = dir / "run.ckpt"};
  run(path, o);
  o.k = 2;
  o.resume = true;
  try {
    run(path, o);
    FAIL() << "resumed a checkpoint of k = 3 with k = 2";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("k=2 (checkpoint: k=3)"), std::string::npos) << e.what();
  }
  std::filesystem::resize_file(o.checkpoint, 100);
  o.k = 3;
  EXPECT_THROW(run(path, o), InputError);
}

TEST(Nmf, NegativeValuesAreClippedAndCountedOrRefused) {
  ScratchDir dir;
  // Noise of 0.05 around small values makes a few percent of the values negative.
  const auto path = make_store(dir, planted_basis(3), 5000, 0.05, 8);
  const NmfResult r = run(path, {.k = 3, .max_epochs = 3});
  EXPECT_GT(r.negatives, 0u);
  EXPECT_LT(r.negatives, r.values / 5);
  EXPECT_EQ(r.values, 5000u * kBands);
  std::uint64_t count = 0;
  const store::Store s = store::Store::open(path);
  const store::BlockReader reader(s, {.collection = "c"});
  store::for_each_block<float>(reader, [&](std::size_t, const RowMatrixXf& x, int) {
#pragma omp critical
    count += std::uint64_t((x.array() < 0).count());
  });
  EXPECT_EQ(r.negatives, count);
  EXPECT_THROW(run(path, {.k = 3, .max_epochs = 3, .negatives = Negatives::reject}), InputError);
}

// Overwrites value (row, band) of collection c's spectra in place, as a writer other than specula could.
void poke(const std::filesystem::path& path, hsize_t row, hsize_t band, float value) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  const hid_t d = H5Dopen2(f, "/collections/c/spectra", H5P_DEFAULT);
  const hid_t space = H5Dget_space(d);
  const hsize_t start[2] = {row, band}, count[2] = {1, 1};
  H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
  const hid_t mem = H5Screate_simple(2, count, nullptr);
  const herr_t written = H5Dwrite(d, H5T_NATIVE_FLOAT, mem, space, H5P_DEFAULT, &value);
  if (written < 0) H5Eprint2(H5E_DEFAULT, stderr);
  ASSERT_GE(written, 0);
  H5Sclose(mem);
  H5Sclose(space);
  H5Dclose(d);
  H5Fclose(f);
}

TEST(Nmf, NonFiniteValuesInAnyBandAreRefused) {
  ScratchDir dir;
  // 13 bands: bands 0-7 are converted eight at a time, 8-12 one by one; both paths must catch them.
  constexpr std::size_t bands = 13, n = 3000;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  store::Collection col;
  col.wavelengths = WavelengthGrid::range(400, 400 + 10.0 * (bands - 1), 10);
  col.units = "reflectance";
  for (std::size_t i = 0; i < n; ++i) col.names.push_back("s" + std::to_string(i));
  for (std::size_t i = 0; i < n * bands; ++i) col.values.push_back(u(rng));
  const std::pair<hsize_t, float> cases[] = {{3, std::numeric_limits<float>::quiet_NaN()},
                                             {11, std::numeric_limits<float>::infinity()},
                                             {7, -std::numeric_limits<float>::infinity()}};
  for (const auto& [band, value] : cases) {
    const auto path = dir / ("bad" + std::to_string(band) + ".h5");
    store::StoreWriter w(path, {});
    w.add_collection("c", col);
    w.commit();
    EXPECT_NO_THROW(run(path, {.k = 2, .max_epochs = 1}));
    poke(path, 2500, band, value);
    try {
      run(path, {.k = 2, .max_epochs = 1});
      ADD_FAILURE() << "no error for band " << band;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos) << e.what();
    }
  }
  // Negatives in both paths are clipped and counted.
  const auto path = dir / "negatives.h5";
  store::StoreWriter w(path, {});
  w.add_collection("c", col);
  w.commit();
  poke(path, 10, 2, -0.5f);
  poke(path, 2999, 12, -1e-30f);
  EXPECT_EQ(run(path, {.k = 2, .max_epochs = 1}).negatives, 2u);
}

TEST(Nmf, RestartsAreComparedByMatchedComponentAngles) {
  Eigen::MatrixXd a = planted_basis(4);
  Eigen::MatrixXd b = a;
  b.row(0).swap(b.row(3));  // same basis, other order
  auto [mean_deg, max_deg] = basis_angles(a, b);
  EXPECT_NEAR(max_deg, 0.0, 1e-6);
  b.row(1) = a.row(2);
  std::tie(mean_deg, max_deg) = basis_angles(a, b);
  EXPECT_GT(max_deg, 1.0);
}

TEST(Nmf, RefusesBadOptions) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(3), 1000, 0.0, 9);
  EXPECT_THROW(run(path, {.k = 0}), UsageError);
  EXPECT_THROW(run(path, {.k = kBands + 1}), UsageError);
  EXPECT_THROW(run(path, {.k = 2, .restarts = 0}), UsageError);
  EXPECT_THROW(run(path, {.k = 2, .tol = -1}), UsageError);
  EXPECT_THROW(parse_init("svd"), UsageError);
  EXPECT_THROW(parse_negatives("abs"), UsageError);
}

TEST(Nmf, WarmUpOnASampleIsThreadIndependentResumableAndCertified) {
  ScratchDir dir;
  // 70000 spectra of 16 bands: 5 blocks; a warm-up sample of every second block.
  const auto path = make_store(dir, planted_basis(5), 70000, 0.01, 12);
  NmfOptions o{.k = 5, .max_epochs = 4, .tol = 0, .warmup_blocks = 2};
  const NmfResult one = run_on(1, path, o);
  const NmfResult two = run_on(2, path, o);
  EXPECT_GT(one.warmup_epochs, 1u);
  EXPECT_EQ(one.warmup_blocks, 3u);
  EXPECT_EQ(one.best_result().history, two.best_result().history);
  EXPECT_TRUE(one.best_result().basis == two.best_result().basis);
  const auto& h = one.best_result().history;
  for (std::size_t e = 1; e < h.size(); ++e) EXPECT_LE(h[e], h[e - 1] * (1 + 1e-12));
  EXPECT_GE(one.rel_error, one.svd_bound);

  o.checkpoint = dir / "warm.ckpt";
  o.on_epoch = [](const EpochReport& e) {
    if (e.epoch == 2) request_interrupt();
  };
  EXPECT_THROW(run(path, o), Interrupted);
  clear_interrupt();
  o.on_epoch = nullptr;
  o.resume = true;
  const NmfResult resumed = run(path, o);
  EXPECT_EQ(resumed.best_result().history, one.best_result().history);
  EXPECT_TRUE(resumed.best_result().basis == one.best_result().basis);
}

// tests/nmf/data/v1-run.ckpt was written by specula's first checkpoint writer (nmf/checkpoint.cpp on raw HDF5 calls,
// before the store's state-file API) for this run (checkpoint set), interrupted after epoch 1 of restart 2. It must
// still load and resume to the uninterrupted run's result; the tolerance allows another CPU's rounding in the epochs
// the fixture holds.
TEST(Nmf, CheckpointOfTheFirstWriterStillResumes) {
  ScratchDir dir;
  const auto path = make_store(dir, planted_basis(3), 3000, 0.01, 12);
  const NmfOptions plain{.k = 3, .restarts = 2, .max_epochs = 4, .tol = 0};
  const NmfResult straight = run(path, plain);
  NmfOptions o = plain;
  o.checkpoint = dir / "v1-run.ckpt";
  std::filesystem::copy_file(SPECULA_SOURCE_DIR "/tests/nmf/data/v1-run.ckpt", o.checkpoint);
  const Checkpoint cp = load_checkpoint(o.checkpoint);
  EXPECT_EQ(cp.restart, 1u);
  EXPECT_EQ(cp.epoch, 1u);
  ASSERT_EQ(cp.done_bases.size(), 1u);
  EXPECT_EQ(cp.n, 3000u);
  EXPECT_EQ(cp.values, 3000u * kBands);
  o.resume = true;
  const NmfResult resumed = run(path, o);
  EXPECT_TRUE(resumed.resumed);
  ASSERT_EQ(resumed.restarts.size(), 2u);
  for (std::size_t r = 0; r < 2; ++r) {
    ASSERT_EQ(resumed.restarts[r].history.size(), straight.restarts[r].history.size());
    for (std::size_t e = 0; e < straight.restarts[r].history.size(); ++e)
      EXPECT_NEAR(resumed.restarts[r].history[e], straight.restarts[r].history[e],
                  1e-9 * straight.restarts[r].history[e])
          << "restart " << r << " epoch " << e;
    EXPECT_LT((resumed.restarts[r].basis - straight.restarts[r].basis).cwiseAbs().maxCoeff(), 1e-9) << r;
  }
}
