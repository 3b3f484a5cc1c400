// A reconstruction's grid and its confidence are written together or not at all (acquire/prior_output.h,
// the store transaction): a failure in the middle of the second leaves the store, or the directory, as it was.
#include "specula/acquire/prior_output.h"

#include <gtest/gtest.h>

#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"
#include "test_support.h"

using namespace specula;

namespace {

store::Grid grid(std::size_t bands, float value) {
  store::Grid g;
  g.wavelengths = WavelengthGrid::range(400, 400 + 10 * double(bands - 1), 10);
  g.brdf.assign(bands * brdf::kMerlCells, value);
  return g;
}

}  // namespace

TEST(PriorOutput, ConfidenceNamesBesideTheGrid) {
  EXPECT_EQ(acquire::confidence_name("rp"), "rp.confidence");
  EXPECT_EQ(acquire::confidence_path("out/x.spgrid"), std::filesystem::path("out/x.confidence.spgrid"));
  const std::vector<float> c(brdf::kMerlCells, 0.5f);
  const store::Grid g = acquire::confidence_grid(c, WavelengthGrid::range(400, 700, 10));
  EXPECT_EQ(g.units, "confidence");
  EXPECT_EQ(g.bands(), 1u);
  EXPECT_EQ(g.wavelengths[0], 550.0);
  EXPECT_THROW(acquire::confidence_grid(std::vector<float>(10), g.wavelengths), UsageError);
}

TEST(PriorOutput, AStoreGetsBothGridsInOneTransactionOrNeither) {
  test::ScratchDir dir;
  const auto path = dir / "out.h5";
  {
    store::StoreWriter w(path, {});
    w.add_grid("a", grid(1, 0.25f));
    w.commit();
  }
  const std::string before = test::read_bytes(path);
  const store::Grid brdf = grid(5, 0.125f), conf = grid(1, 0.75f);
  // Uncompressed, a grid is written band by band: the 6th write is the confidence's.
  store::inject_write_failure_after(5);
  try {
    store::StoreWriter w(path, {.compression = store::Compression::parse("none")});
    acquire::add_prior_grids(w, "rp", brdf, conf);
    w.commit();
    store::inject_write_failure_after(-1);
    FAIL() << "the injected write failure did not surface";
  } catch (const LibraryError& e) {
    store::inject_write_failure_after(-1);
    EXPECT_NE(std::string(e.what()).find("rp.confidence"), std::string::npos) << e.what();
  }
  EXPECT_EQ(test::read_bytes(path), before);
  EXPECT_EQ(store::Store::open(path).grids(), std::vector<std::string>{"a"});
  {
    store::StoreWriter w(path, {});
    acquire::add_prior_grids(w, "rp", brdf, conf);
    w.commit();
  }
  const store::Store s = store::Store::open(path);
  EXPECT_EQ(s.grids(), (std::vector<std::string>{"a", "rp", "rp.confidence"}));
  EXPECT_EQ(s.read_grid("rp.confidence").brdf, conf.brdf);
  EXPECT_EQ(s.read_grid("rp").brdf, brdf.brdf);
}
