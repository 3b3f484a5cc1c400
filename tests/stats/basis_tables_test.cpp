// plot-basis's tables read back: components and eigenvalues as stored, ratios as the eigenvalues' share, cumulative
// sums ending at 1.
#include "specula/stats/basis_tables.h"

#include <gtest/gtest.h>

#include <sstream>

using namespace specula;

namespace {
store::Basis two_by_three() {
  store::Basis b;
  b.method = "pca";
  b.wavelengths = WavelengthGrid({400.0, 500.0, 600.0});
  b.components.resize(2, 3);
  b.components << 0.5, -0.25, 1, 2, 0, -3;
  b.eigenvalues = (Eigen::VectorXd(3) << 3, 1, 0).finished();
  return b;
}
}  // namespace

TEST(BasisTables, ComponentsReadBackAsStoredOneBandALine) {
  const store::Basis b = two_by_three();
  EXPECT_EQ(stats::components_csv(b, 2), "wavelength_nm,c1,c2\n400,0.5,2\n500,-0.25,0\n600,1,-3\n");
  EXPECT_EQ(stats::components_rows(b, 1, ' '), "400 0.5\n500 -0.25\n600 1\n");
}

TEST(BasisTables, ExplainedRatiosAreTheEigenvaluesShareUnlessStored) {
  store::Basis b = two_by_three();
  EXPECT_EQ(stats::eigenvalues_csv(b),
            "index,eigenvalue,explained_ratio,cumulative_ratio\n1,3,0.75,0.75\n2,1,0.25,1\n3,0,0,1\n");
  EXPECT_EQ(stats::eigenvalues_rows(b), "1 3\n2 1\n3 0\n");
  b.explained_variance_ratio = (Eigen::VectorXd(3) << 0.5, 0.5, 0).finished();
  EXPECT_DOUBLE_EQ(stats::explained_ratio(b)[0], 0.5);
  b.eigenvalues.setZero();
  b.explained_variance_ratio.resize(0);
  EXPECT_DOUBLE_EQ(stats::explained_ratio(b).sum(), 0.0);  // nothing to share: divided by 1, not by 0
}
