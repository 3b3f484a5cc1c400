#include "specula/core/huge_pages.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace specula {
namespace {

// The THPeligible flag /proc/self/smaps gives the mapping holding address a (-1: no such mapping or flag).
int eligible(std::uintptr_t a) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.rfind("THPeligible:", 0) == 0) return std::stoi(line.substr(12));
  }
  return -1;
}

bool huge_pages_offered() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string modes;
  std::getline(f, modes);
  return modes.find("[always]") != std::string::npos || modes.find("[madvise]") != std::string::npos;
}

// Advice on any range, aligned or not, shorter than a huge page or not, leaves the values; the 2 MB pages wholly
// inside a range become eligible for huge pages.
TEST(HugePages, AdviceLeavesTheValuesAndMakesTheWholePagesInsideEligible) {
  constexpr std::size_t kTwoMB = std::size_t(1) << 21;
  std::vector<std::uint32_t> v(5 * kTwoMB / sizeof(std::uint32_t));
  std::iota(v.begin(), v.end(), 7u);
  const auto before = v;
  advise_huge_pages(v.data(), 0);
  advise_huge_pages(v.data() + 3, 1000);
  advise_huge_pages(v.data() + 1, v.size() * sizeof(std::uint32_t) - 8);
  EXPECT_EQ(v, before);
  if (!huge_pages_offered()) GTEST_SKIP() << "this system offers no transparent huge pages";
  const std::uintptr_t start = reinterpret_cast<std::uintptr_t>(v.data());
  const std::uintptr_t inside = (start + kTwoMB - 1) / kTwoMB * kTwoMB;
  EXPECT_EQ(eligible(inside), 1);
}

}  // namespace
}  // namespace specula
