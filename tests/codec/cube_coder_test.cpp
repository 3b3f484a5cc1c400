#include "specula/codec/cube_coder.h"

#include <gtest/gtest.h>

#include <random>

#include <vector>
#include "specula/core/error.h"

namespace specula::codec {
namespace {

const wavelet::CubeLayout kLayout{{30, 20, 25}, 3};
constexpr std::size_t kSize = 30 * 20 * 25;

// Codes like a quantised transform: large values in the low cube, sparse small ones elsewhere, a few huge ones.
std::vector<std::int32_t> sparse_codes(unsigned seed, double density) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::geometric_distribution<int> g(0.3);
  std::vector<std::int32_t> q(kSize, 0);
  for (auto& v : q)
    if (u(rng) < density) v = (1 + g(rng)) * (u(rng) < 0.5 ? -1 : 1);
  const auto e = kLayout.low(kLayout.levels);
  for (std::size_t i = 0; i < e[0]; ++i)
    for (std::size_t j = 0; j < e[1]; ++j)
      for (std::size_t k = 0; k < e[2]; ++k) q[(i * 20 + j) * 25 + k] = std::int32_t(1000 + i * 7 - j * 13 + k);
  q[kSize - 1] = (1 << 28) - 1;
  q[kSize / 2] = -(1 << 27);
  return q;
}

TEST(CubeCoder, CodesComeBackExactly) {
  for (const double density : {0.0, 0.01, 0.3, 1.0}) {
    const auto q = sparse_codes(7, density);
    const auto bytes = encode_cube(q, kLayout);
    std::vector<std::int32_t> back(kSize, 99);
    ASSERT_TRUE(decode_cube(bytes, kLayout, back)) << density;
    EXPECT_EQ(back, q) << density;
  }
}

TEST(CubeCoder, SparseCubesCostLittle) {
  const auto empty = encode_cube(std::vector<std::int32_t>(kSize, 0), kLayout);
  EXPECT_LT(empty.size(), 64u);  // 15000 zeros
  EXPECT_LT(encode_cube(sparse_codes(3, 0.01), kLayout).size(), encode_cube(sparse_codes(3, 0.3), kLayout).size());
}

TEST(CubeCoder, TruncatedOrDamagedStreamsStayInBounds) {
  const auto q = sparse_codes(11, 0.2);
  const auto bytes = encode_cube(q, kLayout);
  std::vector<std::int32_t> back(kSize);
  EXPECT_FALSE(decode_cube(std::span(bytes).first(bytes.size() / 2), kLayout, back));
  std::mt19937 rng(1);
  for (int t = 0; t < 20; ++t) {
    auto b = bytes;
    b[rng() % b.size()] ^= 0x5a;
    decode_cube(b, kLayout, back);  // wrong values, never a crash (run under the sanitizers in scripts/test --sanitize)
  }
  EXPECT_THROW(encode_cube(std::vector<std::int32_t>(10), kLayout), UsageError);
}

}  // namespace
}  // namespace specula::codec
