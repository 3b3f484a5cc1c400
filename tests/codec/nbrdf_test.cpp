// Neural BRDFs on the MERL grid (codec/nbrdf.h) against an independent numpy evaluation of the real Sztrajman et
// al. weights in ../shared (tests/codec/nbrdf_reference.py), and the reader's one-line refusals of bad weights.
#include "specula/codec/nbrdf.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <limits>
#include <sstream>

#include "specula/store/h5.h"
#include "test_support.h"

using namespace specula;

namespace {

bool have_h5py() { return std::system("/usr/bin/python3 -c 'import h5py, numpy' >/dev/null 2>&1") == 0; }

// A Keras-layout weights file with every kernel and bias as given (float64 datasets).
void write_weights(const std::filesystem::path& p, const std::vector<Eigen::MatrixXd>& kernels,
                   const std::vector<Eigen::VectorXd>& biases) {
  store::h5::quiet_errors();
  const store::h5::Id f(H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
  ASSERT_TRUE(f.valid());
  for (std::size_t n = 0; n < kernels.size(); ++n) {
    const std::string layer = "dense_" + std::to_string(n + 1);
    const store::h5::Id outer(H5Gcreate2(f, layer.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    const store::h5::Id inner(H5Gcreate2(outer, layer.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    store::h5::write_matrix(inner, "kernel:0", kernels[n], "test");
    const std::vector<double> b(biases[n].data(), biases[n].data() + biases[n].size());
    store::h5::write_vector(inner, "bias:0", b, "test");
  }
}

std::vector<Eigen::MatrixXd> good_kernels() {
  return {Eigen::MatrixXd::Constant(6, 21, 0.1), Eigen::MatrixXd::Constant(21, 21, 0.01),
          Eigen::MatrixXd::Constant(21, 3, 0.02)};
}
std::vector<Eigen::VectorXd> good_biases() {
  return {Eigen::VectorXd::Zero(21), Eigen::VectorXd::Zero(21), Eigen::VectorXd::Constant(3, -0.5)};
}

}  // namespace

TEST(Nbrdf, CellCentresMatchAnIndependentNumpyEvaluationOfTheRealWeights) {
  SPECULA_REQUIRE_SHARED();
  if (!have_h5py()) GTEST_SKIP() << "Debian's python3-h5py is not installed (scripts/setup-deps installs it)";
  const auto dir = test::shared_dir() / "data" / "brdf" / "nbrdf-merl";
  // The peak, mid angles, grazing theta_d, a retro-reflection cell and a cell below the horizon.
  const std::vector<brdf::MerlCell> cells = {{0, 0, 0},  {0, 10, 90}, {3, 40, 17},  {30, 60, 120}, {50, 85, 179},
                                             {89, 1, 0}, {70, 80, 5}, {89, 89, 90}, {10, 20, 30},  {20, 5, 150}};
  for (const char* material : {"red-plastic", "gold-metallic-paint2", "pink-fabric"}) {
    const auto file = dir / (std::string(material) + ".h5");
    const codec::MerlBrdf grid = codec::nbrdf_to_merl(store::read_nbrdf(file));
    std::string cmd =
        "/usr/bin/python3 '" SPECULA_SOURCE_DIR "/tests/codec/nbrdf_reference.py' '" + file.string() + "'";
    for (const auto& c : cells)
      cmd += " " + std::to_string(c.theta_h) + "," + std::to_string(c.theta_d) + "," + std::to_string(c.phi_d);
    const test::RunResult r = test::run_shell(cmd);
    ASSERT_EQ(r.status, 0) << r.output;
    std::istringstream lines(r.output);
    std::size_t seen = 0, with_data = 0;
    for (int i, j, k; lines >> i >> j >> k;) {
      double ref[3];
      lines >> ref[0] >> ref[1] >> ref[2];
      const std::size_t cell = brdf::merl_index({i, j, k});
      ++seen;
      if (ref[0] < 0) {
        EXPECT_FALSE(grid.has_data(cell)) << material << " cell " << i << "," << j << "," << k;
        continue;
      }
      ASSERT_TRUE(grid.has_data(cell)) << material << " cell " << i << "," << j << "," << k;
      ++with_data;
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(grid.value(ch, cell), ref[ch], 1e-9 * std::max(1.0, ref[ch]))
            << material << " cell " << i << "," << j << "," << k << " channel " << ch;
    }
    EXPECT_EQ(seen, cells.size()) << r.output;
    EXPECT_GE(with_data, 6u);
  }
}

TEST(Nbrdf, CellsBelowTheHorizonHaveNoDataAndTheOthersAreEvaluated) {
  test::ScratchDir dir;
  write_weights(dir / "w.h5", good_kernels(), good_biases());
  codec::NbrdfGridReport report;
  const codec::MerlBrdf g = codec::nbrdf_to_merl(store::read_nbrdf(dir / "w.h5"), &report);
  std::size_t valid = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    const bool v = brdf::merl_cell_valid(brdf::merl_cell(cell));
    valid += v;
    ASSERT_EQ(g.has_data(cell), v) << cell;
  }
  EXPECT_EQ(report.cells, valid);
  EXPECT_GT(valid, brdf::kMerlCells / 2);
  // Closed form at the first cell: every hidden unit is 0.1 * sum(inputs), ReLU'd.
  const brdf::HalfDiff hd = brdf::merl_cell_centre({0, 0, 0});
  const Eigen::Vector3d h = brdf::direction(hd.theta_h, 0), d = brdf::direction(hd.theta_d, hd.phi_d);
  const double a = std::max(0.0, 0.1 * (h.sum() + d.sum()));
  const double b = std::max(0.0, 0.01 * 21 * a);
  EXPECT_NEAR(g.value(1, 0), std::max(0.0, std::expm1(0.02 * 21 * b - 0.5)), 1e-12);
}

TEST(Nbrdf, BadWeightsAreRefusedWithOneLineNamingTheFileAndTheDataset) {
  test::ScratchDir dir;
  auto kernels = good_kernels();
  kernels[1] = Eigen::MatrixXd::Constant(21, 20, 0.01);
  write_weights(dir / "shape.h5", kernels, good_biases());
  std::string m = test::error_of([&] { store::read_nbrdf(dir / "shape.h5"); });
  EXPECT_NE(m.find("shape.h5: dense_2/dense_2/kernel:0: shape (21, 20)"), std::string::npos) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos);

  kernels = good_kernels();
  kernels[2](4, 1) = std::numeric_limits<double>::quiet_NaN();
  write_weights(dir / "nan.h5", kernels, good_biases());
  m = test::error_of([&] { store::read_nbrdf(dir / "nan.h5"); });
  EXPECT_NE(m.find("nan.h5: dense_3/dense_3/kernel:0: weight 13 is nan"), std::string::npos) << m;

  kernels = good_kernels();
  kernels.pop_back();
  write_weights(dir / "short.h5", kernels, good_biases());
  m = test::error_of([&] { store::read_nbrdf(dir / "short.h5"); });
  EXPECT_NE(m.find("short.h5: dataset 'dense_3/dense_3/kernel:0' is missing"), std::string::npos) << m;

  test::write_file(dir / "text.h5", "not hdf5\n");
  m = test::error_of([&] { store::read_nbrdf(dir / "text.h5"); });
  EXPECT_NE(m.find("text.h5: not an HDF5 file"), std::string::npos) << m;
  EXPECT_FALSE(store::is_nbrdf(dir / "text.h5"));
  EXPECT_TRUE(store::is_nbrdf(dir / "short.h5"));
}
