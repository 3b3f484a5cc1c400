#include "specula/store/object_spec.h"

#include <gtest/gtest.h>

using specula::store::parse_object_spec;

TEST(ObjectSpec, SplitsAtTheLastColon) {
  const auto s = parse_object_spec("data/db.h5:synth0");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->file, "data/db.h5");
  EXPECT_EQ(s->name, "synth0");
  const auto t = parse_object_spec("odd:dir/db.h5:grid");  // a colon in the path: the name is after the last one
  ASSERT_TRUE(t);
  EXPECT_EQ(t->file, "odd:dir/db.h5");
  EXPECT_EQ(t->name, "grid");
}

TEST(ObjectSpec, NoColonOrNoPathIsNotASpec) {
  EXPECT_FALSE(parse_object_spec("db.h5"));
  EXPECT_FALSE(parse_object_spec(":name"));
  EXPECT_FALSE(parse_object_spec(""));
}

TEST(ObjectSpec, AnEmptyNameIsKeptForTheCallerToRefuse) {
  const auto s = parse_object_spec("db.h5:");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->file, "db.h5");
  EXPECT_TRUE(s->name.empty());
}
