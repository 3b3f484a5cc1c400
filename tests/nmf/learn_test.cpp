// learn_basis on an exactly rank-2 non-negative collection, and the naming conventions.
#include "specula/nmf/learn.h"

#include <gtest/gtest.h>

#include <random>

#include "test_support.h"

using namespace specula;

TEST(LearnBasis, RankTwoDataAndProvenance) {
  test::ScratchDir dir;
  const auto path = dir / "db.h5";
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::size_t n = 300, bands = 6;
  store::Collection c;
  c.wavelengths = WavelengthGrid::range(400, 450, 10);
  c.units = "reflectance";
  const double s1[bands] = {1, 0.8, 0.5, 0.2, 0.1, 0}, s2[bands] = {0, 0.1, 0.3, 0.6, 0.9, 1};
  for (std::size_t i = 0; i < n; ++i) {
    c.names.push_back("s" + std::to_string(i));
    const double a = u(rng), b = u(rng);
    for (std::size_t k = 0; k < bands; ++k) c.values.push_back(float(a * s1[k] + b * s2[k]));
  }
  {
    store::StoreWriter w(path, {});
    w.add_collection("c", c);
    w.commit();
  }
  std::vector<store::Store> stores;
  stores.push_back(store::Store::open(path));
  const nmf::LearnedBasis r = nmf::learn_basis(stores, {.collection = "c"}, {.k = 2, .max_epochs = 200, .tol = 1e-9});
  EXPECT_LT(r.result.rel_error, 1e-3);
  EXPECT_EQ(r.bands, bands);
  EXPECT_EQ(r.basis.method, "nmf");
  EXPECT_EQ(r.basis.n, n);
  EXPECT_EQ(r.basis.k(), 2u);
  EXPECT_EQ(r.basis.source, "collection c");
  EXPECT_EQ(r.basis.provenance.source_file, path.string());
  EXPECT_EQ(r.basis.provenance.importer.rfind("nmf k=2 init=nndsvd seed=0 restarts=1 rel_error=", 0), 0u)
      << r.basis.provenance.importer;
}

TEST(LearnBasis, NamesAndCheckpointPath) {
  EXPECT_EQ(nmf::default_basis_name(7), "nmf7");
  EXPECT_EQ(nmf::default_checkpoint("runs/db.h5", "nmf7"), std::filesystem::path("runs/db.h5.nmf-nmf7.checkpoint"));
  EXPECT_EQ(nmf::init_name(nmf::Init::random), "random");
  EXPECT_EQ(nmf::init_name(nmf::parse_init("nndsvd")), "nndsvd");
}
