// `specula export STORE GRID -o X.binary|X.spgrid`: a store's spectral grid out as RGB MERL under a chosen
// illuminant, or as the exchange file.
#include <gtest/gtest.h>

#include <numbers>

#include "specula/codec/merl.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/store/store.h"
#include "test_support.h"

namespace specula::codec {
namespace {

TEST(ExportGridCli, AGreyGridIsGreyUnderAnyIlluminantAndAColouredOneIsNot) {
  test::ScratchDir dir;
  const WavelengthGrid g = WavelengthGrid::range(400, 700, 10);
  Eigen::VectorXd red = Eigen::VectorXd::Constant(31, 0.1);
  red.tail(10).setConstant(0.7);
  const auto db = dir / "g.h5";
  {
    store::StoreWriter w(db, {});
    for (const auto& [name, rho] :
         {std::pair{"grey", Eigen::VectorXd(Eigen::VectorXd::Constant(31, 0.5))}, std::pair{"red", red}}) {
      store::Grid grid;
      grid.wavelengths = g;
      grid.brdf.resize(31 * brdf::kMerlCells);
      brdf::evaluate_grid(brdf::Lambertian(g, rho), grid.brdf);
      w.add_grid(name, grid);
    }
    w.commit();
  }
  const brdf::StdAngles at{0.3, 0.0, 0.5, 2.0};
  Eigen::Vector3d red_under[2];
  int i = 0;
  for (const char* illum : {"D65", "A"}) {
    for (const char* name : {"grey", "red"}) {
      const auto out = dir / (std::string(name) + "-" + illum + ".binary");
      auto r = test::run_specula("export '" + db.string() + "' " + name + " -o '" + out.string() + "' --illuminant " +
                                 illum);
      ASSERT_EQ(r.status, 0) << r.output;
      const Eigen::Vector3d v = read_merl(out).lookup(at);
      if (std::string(name) == "grey")
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], 0.5 / std::numbers::pi, 2e-3) << illum;
      else
        red_under[i] = v;
    }
    ++i;
  }
  EXPECT_GT(red_under[0][0], 2 * red_under[0][2]);
  EXPECT_GT((red_under[0] - red_under[1]).norm(), 1e-3);  // the same paint looks different under A
  auto r = test::run_specula("export '" + db.string() + "' red -o '" + (dir / "red.spgrid").string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_grid_file(dir / "red.spgrid").brdf, store::Store::open(db).read_grid("red").brdf);
  r = test::run_specula("export '" + db.string() + "' red -o '" + (dir / "red.png").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
}

}  // namespace
}  // namespace specula::codec
