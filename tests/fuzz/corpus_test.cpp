// Every file of every fuzz corpus (tests/fuzz/corpus/<target>/) through the target's entry function in the normal
// build: each is read or rejected with a specula::Error, never a crash, a broken invariant or another exception.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "entries.h"
#include "specula/core/error.h"

namespace specula::fuzz {
namespace {

namespace fs = std::filesystem;

const fs::path kCorpus = fs::path(SPECULA_SOURCE_DIR) / "tests" / "fuzz" / "corpus";

std::vector<std::uint8_t> bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class Corpus : public ::testing::TestWithParam<Target> {};

TEST_P(Corpus, EveryFileIsReadOrRejectedWithASpeculaError) {
  const Target t = GetParam();
  const fs::path dir = kCorpus / t.name;
  ASSERT_TRUE(fs::is_directory(dir)) << dir << " is missing: every fuzz target has a seed corpus";
  std::size_t files = 0, accepted = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    ++files;
    const auto input = bytes_of(e.path());
    try {
      t.entry(input);
      ++accepted;
    } catch (const Error&) {
    } catch (const std::exception& x) {
      ADD_FAILURE() << e.path() << ": " << x.what();
    } catch (...) {
      ADD_FAILURE() << e.path() << ": a non-standard exception";
    }
  }
  EXPECT_GE(files, 2u) << dir;
  // The seeds are valid files: a corpus the reader rejects entirely exercises only its error paths.
  EXPECT_GE(accepted, 1u) << dir;
}

INSTANTIATE_TEST_SUITE_P(Fuzz, Corpus, ::testing::ValuesIn(targets()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Corpus, EveryTargetHasACorpusAndEveryCorpusATarget) {
  std::vector<std::string> dirs;
  for (const auto& e : fs::directory_iterator(kCorpus)) dirs.push_back(e.path().filename().string());
  std::vector<std::string> names;
  for (const auto& t : targets()) names.emplace_back(t.name);
  std::sort(dirs.begin(), dirs.end());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(dirs, names);
}

}  // namespace
}  // namespace specula::fuzz
