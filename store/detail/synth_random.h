#pragma once
// Inside store/ only: the random streams of the synthetic images (synth.cpp): splitmix64 seeding and mixing,
// xoshiro256** for the scene's choices and eight side-by-side xoshiro256** streams turned into normal deviates by
// an inverse-CDF table for the sensor noise.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <vector>

namespace specula::store::synth_detail {

/// splitmix64: the next output, advancing `state`.
inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// A seed from two values.
inline std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  std::uint64_t s = a ^ (b * 0xD1B54A32D192ED03ull);
  splitmix64(s);
  return splitmix64(s);
}

/// xoshiro256** (Blackman & Vigna), seeded through splitmix64.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) {
    for (auto& w : s_) w = splitmix64(seed);
  }
  std::uint64_t next() {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  double log_uniform(double a, double b) { return a * std::exp(std::log(b / a) * uniform()); }
  /// Integer in [lo, hi] inclusive.
  int integer(int lo, int hi) {
    return lo + static_cast<int>((next() >> 32) % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool chance(double p) { return uniform() < p; }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::array<std::uint64_t, 4> s_{};
};

constexpr int kNormalBits = 12;
constexpr std::size_t kNormalSize = std::size_t{1} << kNormalBits;

/// Standard normal quantiles at (i + 0.5) / 4096, rescaled to unit variance.
inline const std::array<float, kNormalSize>& normal_table() {
  static const std::array<float, kNormalSize> table = [] {
    std::array<double, kNormalSize> q{};
    for (std::size_t i = 0; i < kNormalSize; ++i) {
      const double p = (static_cast<double>(i) + 0.5) / static_cast<double>(kNormalSize);
      double lo = -10, hi = 10;
      for (int it = 0; it < 80; ++it) {  // bisection on Phi(x) = p
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p ? lo : hi) = mid;
      }
      q[i] = 0.5 * (lo + hi);
    }
    double var = 0;
    for (double v : q) var += v * v;
    var /= static_cast<double>(kNormalSize);
    const double scale = 1.0 / std::sqrt(var);
    std::array<float, kNormalSize> t{};
    for (std::size_t i = 0; i < kNormalSize; ++i) t[i] = static_cast<float>(q[i] * scale);
    return t;
  }();
  return table;
}

/// Approximately standard normal deviates from eight xoshiro256** streams run side by side (so the
/// compiler can vectorise them), each 64-bit output giving five deviates by table lookup on 12-bit slices.
class NormalStream {
  using Lanes = std::uint64_t __attribute__((vector_size(64)));  // GCC/Clang vector extension, 8 lanes

 public:
  static constexpr std::size_t kLanes = 8, kPerStep = 5 * kLanes, kChunk = 80;  // kChunk: lcm(kPerStep, 16)
  /// Deviates come in blocks of `block` (a multiple of 16), each 64-byte aligned.
  NormalStream(std::uint64_t seed, std::size_t block) : block_(block) {
    for (std::size_t l = 0; l < kLanes; ++l) {
      s0_[l] = splitmix64(seed);
      s1_[l] = splitmix64(seed);
      s2_[l] = splitmix64(seed);
      s3_[l] = splitmix64(seed);
    }
    size_ = std::max<std::size_t>(4 * block, 320);
    size_ = (size_ + kChunk - 1) / kChunk * kChunk;
    storage_.resize(size_ + 16);
    buf_ = storage_.data();
    while (reinterpret_cast<std::uintptr_t>(buf_) % 64 != 0) ++buf_;
    pos_ = size_;
  }
  /// The next block of deviates.
  const float* take() {
    if (pos_ + block_ > size_) refill();
    const float* p = buf_ + pos_;
    pos_ += block_;
    return p;
  }

 private:
  void refill() {
    const float* table = normal_table().data();
    Lanes s0 = s0_, s1 = s1_, s2 = s2_, s3 = s3_;
    for (std::size_t step = 0; step < size_; step += kPerStep) {
      // xoshiro256** on all lanes at once: w = rotl(s1 * 5, 7) * 9
      const Lanes x5 = s1 + (s1 << 2);
      const Lanes r7 = (x5 << 7) | (x5 >> 57);
      const Lanes w = r7 + (r7 << 3);
      const Lanes t = s1 << 17;
      s2 ^= s0;
      s3 ^= s1;
      s1 ^= s2;
      s0 ^= s3;
      s2 ^= t;
      s3 = (s3 << 45) | (s3 >> 19);
      float* out = buf_ + step;
      for (std::size_t k = 0; k < 5; ++k) {
        const Lanes idx = (w >> (kNormalBits * k)) & (kNormalSize - 1);
        for (std::size_t l = 0; l < kLanes; ++l) out[k * kLanes + l] = table[idx[l]];
      }
    }
    s0_ = s0;
    s1_ = s1;
    s2_ = s2;
    s3_ = s3;
    pos_ = 0;
  }
  Lanes s0_, s1_, s2_, s3_;
  std::vector<float> storage_;
  float* buf_ = nullptr;
  std::size_t block_, size_ = 0, pos_ = 0;
};

}  // namespace specula::store::synth_detail
