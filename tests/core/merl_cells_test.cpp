// merl_valid_cells against merl_cell_valid asked cell by cell, a separately written test of each cell's centre.
#include "specula/core/merl_cells.h"

#include <gtest/gtest.h>

#include "specula/core/brdf_geometry.h"

namespace specula::brdf {
namespace {

// The process-wide list against merl_cell_valid asked cell by cell; it is built once, so a second call returns the
// same object.
TEST(MerlCells, AreTheCellsMerlCellValidHoldsFor) {
  std::vector<std::uint32_t> want;
  for (std::size_t i = 0; i < kMerlCells; ++i)
    if (merl_cell_valid(merl_cell(i))) want.push_back(std::uint32_t(i));
  const std::vector<std::uint32_t>& got = merl_valid_cells();
  EXPECT_EQ(got, want);
  EXPECT_EQ(&merl_valid_cells(), &got);
  EXPECT_GT(want.size(), kMerlCells / 2);
  EXPECT_LT(want.size(), kMerlCells);
}

}  // namespace
}  // namespace specula::brdf
