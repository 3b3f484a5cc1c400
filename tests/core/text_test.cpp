#include "specula/core/text.h"

#include <gtest/gtest.h>

namespace specula {
namespace {

TEST(Text, LowerTouchesOnlyAsciiLetters) {
  EXPECT_EQ(lower("Wavelength Units = µm 2A"), "wavelength units = µm 2a");
  EXPECT_EQ(lower(""), "");
}

TEST(Text, CollapseSpacesTrimsAndJoinsRuns) {
  EXPECT_EQ(collapse_spaces("  data \t  ignore\tvalue \r\n"), "data ignore value");
  EXPECT_EQ(collapse_spaces("one"), "one");
  EXPECT_EQ(collapse_spaces(" \t "), "");
}

TEST(Text, TrimAndPrintable) {
  EXPECT_EQ(trim("\t x y \n"), "x y");
  EXPECT_EQ(printable("a\x01"
                      "b"),
            "a?b");
}

}  // namespace
}  // namespace specula
