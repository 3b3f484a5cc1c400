// The optional `parameterisation` of a BRDF grid (docs/store-format.md): kept through the store as written, absent
// for grids written without one (as every store before it), refused when malformed with the store left as it was.
#include <gtest/gtest.h>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

namespace {

Grid small_grid() {
  Grid g;
  g.wavelengths = WavelengthGrid({450, 550});
  g.brdf.assign(2 * brdf::kMerlCells, 0.25f);
  return g;
}

GridParameterisation parameterisation() {
  GridParameterisation p;
  p.phi_i = {0.0f};
  p.theta_i = {0.0f, 0.5f, 1.2f};
  p.ndf_width = 5;
  p.ndf_height = 2;
  for (int k = 0; k < 10; ++k) p.ndf.push_back(3.0f / float(k + 1));
  p.sigma_width = 4;
  p.sigma_height = 2;
  for (int k = 0; k < 8; ++k) p.sigma.push_back(1.0f - 0.1f * float(k % 4));
  p.vndf_width = 4;
  p.vndf_height = 3;
  for (int k = 0; k < 36; ++k) p.vndf.push_back(0.5f + 0.125f * float(k));
  p.resolution = 6;
  p.description = "hand-made";
  return p;
}

TEST(GridParameterisation, RoundTripsThroughTheStoreAndIsAbsentWhenNotWritten) {
  test::ScratchDir dir;
  Grid with = small_grid();
  with.parameterisation = parameterisation();
  {
    StoreWriter w(dir / "s.h5", {});
    w.add_grid("with", with);
    w.add_grid("without", small_grid());
    w.commit();
  }
  const Store s = Store::open(dir / "s.h5");
  const Grid r = s.read_grid("with");
  ASSERT_TRUE(r.parameterisation);
  EXPECT_EQ(*r.parameterisation, parameterisation());
  EXPECT_TRUE(r.brdf == with.brdf);
  EXPECT_FALSE(s.read_grid("without").parameterisation);
}

TEST(GridParameterisation, AMalformedOneIsRefusedAndTheStoreKeptAsItWas) {
  test::ScratchDir dir;
  {
    StoreWriter w(dir / "s.h5", {});
    w.add_grid("a", small_grid());
    w.commit();
  }
  Grid bad = small_grid();
  bad.parameterisation = parameterisation();
  bad.parameterisation->vndf.pop_back();
  {
    StoreWriter w(dir / "s.h5", {});
    EXPECT_THROW(w.add_grid("bad", bad), UsageError);
    w.commit();
  }
  EXPECT_EQ(Store::open(dir / "s.h5").grids(), std::vector<std::string>{"a"});
}

}  // namespace
