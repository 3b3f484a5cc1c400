#include "specula/codec/cube_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdlib>

#include "specula/codec/range_coder.h"
#include "specula/core/error.h"

namespace specula::codec {
namespace {

constexpr int kLevelClasses = 3;   // finest, next, all coarser
constexpr int kExponentBits = 20;  // adaptive unary exponent positions (more share the last)
constexpr int kMaxExponent = 30;

constexpr std::size_t kBlock = 8;  // zero blocks: 8 x 8 x 8 coefficients of a subband

struct Contexts {
  std::array<rc::Bit, kLevelClasses> band_zero;
  std::array<rc::Bit, kLevelClasses * 2> block_zero;
  std::array<rc::Bit, kLevelClasses * 4 * 2> significant;
  std::array<rc::Bit, kLevelClasses * 3> above_one;
  std::array<rc::Bit, kLevelClasses * kExponentBits> exponent;
  rc::Bit low_zero;
  std::array<rc::Bit, kExponentBits> low_exponent;
};

// One traversal serves both directions: the encoder reads q, the decoder writes it, so the contexts can never
// disagree between them.
template <class Coder>
struct Traversal {
  static constexpr bool kDecode = std::is_same_v<Coder, rc::Decoder>;
  Coder& rc;
  std::int32_t* q;
  const wavelet::CubeLayout& c;
  Contexts ctx{};
  std::vector<std::uint8_t> sig;

  unsigned bit(rc::Bit& b, unsigned v) { return rc::code_bit(rc, b, v); }
  std::uint32_t direct(std::uint32_t v, int n) { return rc::code_direct(rc, v, n); }
  // Exp-Golomb of v >= 0: the exponent e = floor(log2(v + 1)) in unary with adaptive bits, then e direct bits.
  std::uint32_t exp_golomb(std::uint32_t v, rc::Bit* exponent) {
    const int e_in = kDecode ? 0 : std::bit_width(v + 1) - 1;
    int e = 0;
    while (e < kMaxExponent && bit(exponent[std::min(e, kExponentBits - 1)], e < e_in ? 1u : 0u)) ++e;
    const std::uint32_t rest = direct(kDecode ? 0 : (v + 1) - (1u << e), e);
    return (1u << e) + rest - 1;
  }

  void low_cube() {
    const auto e = c.low(c.levels);
    const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
    for (std::size_t i = 0; i < e[0]; ++i)
      for (std::size_t j = 0; j < e[1]; ++j)
        for (std::size_t k = 0; k < e[2]; ++k) {
          const std::size_t at = i * s0 + j * s1 + k;
          const std::int64_t pred = k > 0 ? q[at - 1] : j > 0 ? q[at - s1] : i > 0 ? q[at - s0] : 0;
          const std::int64_t d = kDecode ? 0 : std::int64_t(q[at]) - pred;
          std::int64_t r = 0;
          if (bit(ctx.low_zero, d != 0)) {
            const unsigned negative = direct(d < 0, 1);
            const std::uint32_t mag =
                exp_golomb(kDecode ? 0 : std::uint32_t(std::llabs(d) - 1), ctx.low_exponent.data()) + 1;
            r = negative ? -std::int64_t(mag) : std::int64_t(mag);
          }
          if constexpr (kDecode) q[at] = std::int32_t(std::clamp<std::int64_t>(pred + r, INT32_MIN, INT32_MAX));
          sig[at] = 1;
        }
  }

  // Whether any code in [r0, r1) x [r2, r3) x [r4, r5) is non-zero (encoder only).
  bool any(const std::array<std::array<std::size_t, 2>, 3>& r) const {
    const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
    for (std::size_t i = r[0][0]; i < r[0][1]; ++i)
      for (std::size_t j = r[1][0]; j < r[1][1]; ++j)
        for (std::size_t k = r[2][0]; k < r[2][1]; ++k)
          if (q[i * s0 + j * s1 + k] != 0) return true;
    return false;
  }

  void zero(const std::array<std::array<std::size_t, 2>, 3>& r) {
    const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
    for (std::size_t i = r[0][0]; i < r[0][1]; ++i)
      for (std::size_t j = r[1][0]; j < r[1][1]; ++j)
        for (std::size_t k = r[2][0]; k < r[2][1]; ++k) {
          if constexpr (kDecode) q[i * s0 + j * s1 + k] = 0;
          sig[i * s0 + j * s1 + k] = 0;
        }
  }

  // One subband: a flag when it is all zero, else blocks of kBlock^3 with a flag each (context: level class and
  // whether the parent block was non-zero), and the coefficients of non-zero blocks.
  void detail(int l, int o) {
    const std::array<std::array<std::size_t, 2>, 3> r{c.range(l, o, 0), c.range(l, o, 1), c.range(l, o, 2)};
    const int lc = std::min(l, kLevelClasses - 1);
    if (!bit(ctx.band_zero[std::size_t(lc)], kDecode ? 0 : any(r))) return zero(r);
    const bool has_parent = l + 1 < c.levels;
    std::array<std::array<std::size_t, 2>, 3> pr{};
    if (has_parent) pr = {c.range(l + 1, o, 0), c.range(l + 1, o, 1), c.range(l + 1, o, 2)};
    for (std::size_t i0 = r[0][0]; i0 < r[0][1]; i0 += kBlock)
      for (std::size_t j0 = r[1][0]; j0 < r[1][1]; j0 += kBlock)
        for (std::size_t k0 = r[2][0]; k0 < r[2][1]; k0 += kBlock) {
          const std::array<std::array<std::size_t, 2>, 3> b{{{i0, std::min(i0 + kBlock, r[0][1])},
                                                             {j0, std::min(j0 + kBlock, r[1][1])},
                                                             {k0, std::min(k0 + kBlock, r[2][1])}}};
          int parent = 0;
          if (has_parent) {
            std::array<std::array<std::size_t, 2>, 3> p{};
            for (std::size_t a = 0; a < 3; ++a)
              p[a] = {std::min(pr[a][0] + (b[a][0] - r[a][0]) / 2, pr[a][1] - 1),
                      std::min(pr[a][0] + (b[a][1] - r[a][0] + 1) / 2, pr[a][1])};
            parent = any_significant(p);
          }
          if (!bit(ctx.block_zero[std::size_t(lc * 2 + parent)], kDecode ? 0 : any(b))) {
            zero(b);
            continue;
          }
          coefficients(l, o, b, r, pr, has_parent, lc);
        }
  }

  bool any_significant(const std::array<std::array<std::size_t, 2>, 3>& r) const {
    const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
    for (std::size_t i = r[0][0]; i < r[0][1]; ++i)
      for (std::size_t j = r[1][0]; j < r[1][1]; ++j)
        for (std::size_t k = r[2][0]; k < r[2][1]; ++k)
          if (sig[i * s0 + j * s1 + k]) return true;
    return false;
  }

  void coefficients(int, int, const std::array<std::array<std::size_t, 2>, 3>& b,
                    const std::array<std::array<std::size_t, 2>, 3>& r,
                    const std::array<std::array<std::size_t, 2>, 3>& pr, bool has_parent, int lc) {
    const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
    for (std::size_t i = b[0][0]; i < b[0][1]; ++i)
      for (std::size_t j = b[1][0]; j < b[1][1]; ++j)
        for (std::size_t k = b[2][0]; k < b[2][1]; ++k) {
          const std::size_t at = i * s0 + j * s1 + k;
          const int n = (i > r[0][0] && sig[at - s0]) + (j > r[1][0] && sig[at - s1]) + (k > r[2][0] && sig[at - 1]);
          int parent = 0;
          if (has_parent) {
            const std::size_t pi = std::min(pr[0][0] + (i - r[0][0]) / 2, pr[0][1] - 1);
            const std::size_t pj = std::min(pr[1][0] + (j - r[1][0]) / 2, pr[1][1] - 1);
            const std::size_t pk = std::min(pr[2][0] + (k - r[2][0]) / 2, pr[2][1] - 1);
            parent = sig[pi * s0 + pj * s1 + pk];
          }
          const std::int32_t v = kDecode ? 0 : q[at];
          const unsigned s = bit(ctx.significant[std::size_t((lc * 4 + n) * 2 + parent)], v != 0);
          std::int32_t out = 0;
          if (s) {
            const unsigned negative = direct(v < 0, 1);
            const std::uint32_t mag_in = kDecode ? 0 : std::uint32_t(std::abs(std::int64_t(v)));
            std::uint32_t mag = 1;
            if (bit(ctx.above_one[std::size_t(lc * 3 + std::min(n, 2))], mag_in > 1))
              mag = 2 + exp_golomb(kDecode ? 0 : mag_in - 2, ctx.exponent.data() + lc * kExponentBits);
            const auto m = std::int32_t(std::min<std::uint32_t>(mag, INT32_MAX));
            out = negative ? -m : m;
          }
          if constexpr (kDecode) q[at] = out;
          sig[at] = s;
        }
  }

  void run() {
    sig.assign(c.dims[0] * c.dims[1] * c.dims[2], 0);
    low_cube();
    for (int l = c.levels - 1; l >= 0; --l)
      for (int o = 1; o < 8; ++o) detail(l, o);
  }
};

void check(std::size_t n, const wavelet::CubeLayout& c) {
  if (n != c.dims[0] * c.dims[1] * c.dims[2])
    throw UsageError("cube coder: " + std::to_string(n) + " coefficients do not match the cube's layout");
}

// The mask coder's traversal, shared by both directions as Traversal is.
template <class Coder>
void code_mask(Coder& rc, std::uint8_t* m, const std::uint8_t* prior, const std::array<std::size_t, 3>& d) {
  constexpr bool kDecode = std::is_same_v<Coder, rc::Decoder>;
  std::array<rc::Bit, 128 * 3> ctx{};
  const std::size_t s1 = d[2], s0 = d[1] * d[2];
  for (std::size_t i = 0; i < d[0]; ++i)
    for (std::size_t j = 0; j < d[1]; ++j)
      for (std::size_t k = 0; k < d[2]; ++k) {
        const std::size_t at = i * s0 + j * s1 + k;
        const unsigned a = k > 0 && m[at - 1], b = j > 0 && m[at - s1], c = i > 0 && m[at - s0];
        const unsigned e = j > 0 && k + 1 < d[2] && m[at - s1 + 1], f = j > 0 && k > 0 && m[at - s1 - 1];
        const unsigned g = i > 0 && k + 1 < d[2] && m[at - s0 + 1];
        const std::size_t mirror = d[2] - 1 - k;  // already coded past the middle of axis 2
        const unsigned h = mirror < k ? 1u + m[at - k + mirror] : 0u;
        rc::Bit& bit = ctx[(a | b << 1 | c << 2 | e << 3 | f << 4 | g << 5 | unsigned(prior[at] != 0) << 6) + 128 * h];
        if constexpr (kDecode) {
          m[at] = std::uint8_t(rc.decode(bit));
        } else {
          rc.encode(bit, m[at] != 0);
        }
      }
}

}  // namespace

std::vector<std::uint8_t> encode_mask(std::span<const std::uint8_t> mask, std::span<const std::uint8_t> prior,
                                      const std::array<std::size_t, 3>& dims) {
  if (mask.size() != dims[0] * dims[1] * dims[2] || prior.size() != mask.size())
    throw UsageError("mask coder: mask and prior must both hold dims[0] x dims[1] x dims[2] values");
  std::vector<std::uint8_t> m(mask.begin(), mask.end());
  for (auto& v : m) v = v != 0;
  rc::Encoder enc;
  code_mask(enc, m.data(), prior.data(), dims);
  return enc.finish();
}

bool decode_mask(std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> prior,
                 const std::array<std::size_t, 3>& dims, std::span<std::uint8_t> mask) {
  if (mask.size() != dims[0] * dims[1] * dims[2] || prior.size() != mask.size())
    throw UsageError("mask coder: mask and prior must both hold dims[0] x dims[1] x dims[2] values");
  rc::Decoder dec(bytes);
  code_mask(dec, mask.data(), prior.data(), dims);
  return !dec.overrun();
}

std::vector<std::uint8_t> encode_cube(std::span<const std::int32_t> q, const wavelet::CubeLayout& layout) {
  check(q.size(), layout);
  for (const std::int32_t v : q)
    if (v == INT32_MIN) throw UsageError("cube coder: a coefficient of -2^31 cannot be coded");
  rc::Encoder enc;
  Traversal<rc::Encoder>{enc, const_cast<std::int32_t*>(q.data()), layout}.run();
  return enc.finish();
}

bool decode_cube(std::span<const std::uint8_t> bytes, const wavelet::CubeLayout& layout, std::span<std::int32_t> q) {
  check(q.size(), layout);
  rc::Decoder dec(bytes);
  Traversal<rc::Decoder>{dec, q.data(), layout}.run();
  return !dec.overrun();
}

}  // namespace specula::codec
