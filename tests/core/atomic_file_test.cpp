#include "specula/core/atomic_file.h"

#include <gtest/gtest.h>

#include <fstream>

#include "specula/core/error.h"
#include "test_support.h"

using specula::AtomicOutput;

TEST(AtomicOutput, TargetAppearsOnlyOnCommit) {
  specula::test::ScratchDir dir;
  auto target = dir / "out.bin";
  {
    AtomicOutput out(target);
    std::ofstream(out.temp_path()) << "hello";
    EXPECT_FALSE(std::filesystem::exists(target));
    out.commit();
  }
  EXPECT_EQ(specula::test::read_bytes(target), "hello");
}

TEST(AtomicOutput, AbandonedOutputLeavesTargetUntouchedAndNoTemporary) {
  specula::test::ScratchDir dir;
  auto target = dir / "store.h5";
  std::ofstream(target) << "original";
  {
    AtomicOutput out(target, /*copy_existing=*/true);
    EXPECT_EQ(specula::test::read_bytes(out.temp_path()), "original");
    std::ofstream(out.temp_path(), std::ios::app) << " plus a half-written change";
  }
  EXPECT_EQ(specula::test::read_bytes(target), "original");
  std::size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir.path())) (void)e, ++files;
  EXPECT_EQ(files, 1u);
}

TEST(AtomicOutput, SignalPathRemovesPendingTemporaries) {
  specula::test::ScratchDir dir;
  AtomicOutput out(dir / "x.h5");
  std::ofstream(out.temp_path()) << "partial";
  ASSERT_TRUE(std::filesystem::exists(out.temp_path()));
  specula::remove_pending_temporaries();
  EXPECT_FALSE(std::filesystem::exists(out.temp_path()));
}

TEST(AtomicOutput, MissingDirectoryIsAnInputError) {
  EXPECT_THROW(AtomicOutput("/nonexistent-dir-specula/x.h5"), specula::InputError);
}
