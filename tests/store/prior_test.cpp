// The "priors" kind (store/prior.h): a prior's components read back range by range equal the slices of what was
// written, both for ranges of whole chunks (decoded here, chunk by chunk) and for others (HDF5 decodes them); the
// tables read without the components; and a range or buffer that does not fit, or a prior that is not there, is
// refused.
#include "specula/store/prior.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "specula/core/error.h"
#include "specula/store/h5.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using namespace specula::store;

TEST(StorePrior, ComponentsReadBackRangeByRangeAcrossChunks) {
  constexpr std::size_t cells = kPriorBlockCells + 4500, k = 3;
  PriorTables t{.wavelengths = {400, 700}, .knots = {400, 700}, .variances = {3, 2, 1}, .epsilon = 1e-3};
  t.reference.assign(cells, 0.5f);
  t.mean.assign(cells, -0.25f);
  for (std::size_t i = 0; i < k * cells; ++i) t.components.push_back(float(i % 9973) - 4986.5f);
  t.training = {"a", "b"};
  test::ScratchDir dir;
  {
    StoreWriter w(dir / "db.h5", {});
    w.add_prior("p", t);
    w.commit();
  }
  const Store s = Store::open(dir / "db.h5");
  const PriorTables tables = s.read_prior("p", cells, false);
  EXPECT_TRUE(tables.components.empty());
  EXPECT_EQ(tables.mean, t.mean);
  EXPECT_EQ(tables.variances, t.variances);
  EXPECT_EQ(s.read_prior("p", cells).components, t.components);
  for (const auto& [first, count] : {std::pair<std::size_t, std::size_t>{0, cells},
                                     {kPriorBlockCells, cells - kPriorBlockCells},
                                     {kPriorBlockCells - 7, 20},
                                     {cells - 1, 1},
                                     {12, 0}}) {
    std::vector<float> out(k * count, -1.0f), expect;
    for (std::size_t q = 0; q < k; ++q)
      for (std::size_t i = first; i < first + count; ++i) expect.push_back(t.components[q * cells + i]);
    s.read_prior_components("p", first, count, out);
    EXPECT_EQ(out, expect) << first << " + " << count;
  }
  std::vector<float> out(k * 10);
  EXPECT_THROW(s.read_prior_components("p", cells - 9, 10, out), UsageError);
  EXPECT_THROW(s.read_prior_components("p", 0, 11, out), UsageError);
  const std::string m = test::error_of([&] { s.read_prior_components("q", 0, 10, out); });
  EXPECT_NE(m.find("db.h5: no prior 'q' (priors: p"), std::string::npos) << m;
  EXPECT_THROW(s.read_prior("p", cells + 1, false), InputError);  // the components' shape is checked
}

TEST(StorePrior, CeilingRetroExponentsAndRiseMapsRoundTripAndOlderPriorsReadWithout) {
  constexpr std::size_t cells = 1000;
  PriorTables t{.wavelengths = {400, 700}, .knots = {400, 700}, .variances = {2, 1}, .epsilon = 1e-3};
  t.reference.assign(cells, 0.5f);
  t.mean.assign(cells, -0.25f);
  for (std::size_t i = 0; i < cells; ++i) t.ceiling.push_back(float(i) * 0.5f);
  t.components.assign(2 * cells, 0.125f);
  t.training = {"a", "b"};
  PriorTables old = t;  // the layout of version 1: no ceiling
  old.ceiling.clear();
  PriorTables learned = t;  // version 3: the retro band's exponents
  learned.retro_exponents = {2.0, 1.5, 1.4};
  PriorTables bad_exponent = learned;
  bad_exponent.retro_exponents[1] = 0;
  PriorTables risen = learned;  // version 4: the rise maps, 2 + 8 + 18 values for widths 1, 2, 3
  for (int i = 0; i < 28; ++i) risen.retro_rise.push_back(0.25 * i - 3);
  PriorTables bad_rise = risen;
  bad_rise.retro_rise[9] = std::nan("");
  PriorTables negative = t;
  negative.ceiling[17] = -1.0f;
  test::ScratchDir dir;
  {
    StoreWriter w(dir / "db.h5", {});
    w.add_prior("p", t);
    w.add_prior("old", old);
    w.add_prior("negative", negative);
    w.add_prior("learned", learned);
    w.add_prior("bad_exponent", bad_exponent);
    w.add_prior("risen", risen);
    w.add_prior("bad_rise", bad_rise);
    w.commit();
  }
  const Store s = Store::open(dir / "db.h5");
  EXPECT_EQ(s.read_prior("p", cells, false).ceiling, t.ceiling);
  EXPECT_TRUE(s.read_prior("old", cells).ceiling.empty());
  EXPECT_EQ(s.read_prior("old", cells).mean, t.mean);
  EXPECT_TRUE(s.read_prior("p", cells, false).retro_exponents.empty());  // version 2: none learned
  EXPECT_EQ(s.read_prior("learned", cells, false).retro_exponents, learned.retro_exponents);
  EXPECT_EQ(s.read_prior("learned", cells, false).ceiling, t.ceiling);
  EXPECT_TRUE(s.read_prior("learned", cells, false).retro_rise.empty());  // version 3: no rise maps
  EXPECT_EQ(s.read_prior("risen", cells, false).retro_rise, risen.retro_rise);
  EXPECT_EQ(s.read_prior("risen", cells, false).retro_exponents, learned.retro_exponents);
  for (const char* name : {"negative", "bad_exponent", "bad_rise"}) {
    const std::string m = test::error_of([&] { s.read_prior(name, cells); });
    EXPECT_NE(m.find(std::string("/priors/") + name +
                     ": malformed prior (knots, epsilon, variances, a negative ceiling, retro exponents or rise maps)"),
              std::string::npos)
        << m;
  }
  {                              // a version-3 prior whose table was removed by hand
    std::filesystem::path data;  // the prior's immutable data file (docs/store-format.md)
    for (const auto& e : std::filesystem::directory_iterator(dir / "db.h5.d" / "objects" / "priors"))
      if (e.path().filename().string().starts_with("learned@")) data = e.path();
    hid_t f = H5Fopen(data.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(H5Ldelete(f, "/priors/learned/retro_exponents", H5P_DEFAULT), 0);
    H5Fclose(f);
  }
  const std::string gone = test::error_of([&] { Store::open(dir / "db.h5").read_prior("learned", cells, false); });
  EXPECT_NE(gone.find("db.h5: /priors/learned: dataset 'retro_exponents' is missing"), std::string::npos) << gone;
  old.retro_exponents = {2.0};  // exponents without a ceiling: no version holds that
  StoreWriter w(dir / "db2.h5", {});
  EXPECT_THROW(w.add_prior("old", old), UsageError);
  risen.retro_rise.pop_back();  // not 2 w^2 values for each of the exponents' widths
  EXPECT_THROW(w.add_prior("risen", risen), UsageError);
  EXPECT_EQ(retro_rise_values(3), 28u);
  t.ceiling.pop_back();
  EXPECT_THROW(w.add_prior("p", t), UsageError);
}
