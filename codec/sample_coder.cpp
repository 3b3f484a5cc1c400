#include "specula/codec/sample_coder.h"

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <type_traits>

#include "specula/codec/range_coder.h"

namespace specula::codec {
namespace {

constexpr int kExponentBits = 28;  // an exponent of 28 or more is past kMaxSampleCode

struct IntegerContexts {
  rc::Bit zero, sign;
  std::array<rc::Bit, kExponentBits> exponent;
  std::array<rc::Bit, kExponentBits> lead;  // the mantissa's leading bit, per exponent
};

// One traversal serves both directions: the encoder reads the codes, the decoder writes them, so the contexts can
// never disagree between them.
template <class Coder>
struct Traversal {
  static constexpr bool kDecode = std::is_same_v<Coder, rc::Decoder>;
  Coder& rc;
  bool in_range = true;

  unsigned bit(rc::Bit& b, unsigned v) { return rc::code_bit(rc, b, v); }
  std::uint32_t direct(std::uint32_t v, int n) { return rc::code_direct(rc, v, n); }
  // v in [0, 2^bits), most significant bit first, each bit in the context of the bits above it (LZMA's bit tree).
  std::uint32_t tree(std::uint32_t v, int bits, std::vector<rc::Bit>& ctx) {
    std::uint32_t m = 1;
    for (int i = bits - 1; i >= 0; --i) m = (m << 1) | bit(ctx[m], (v >> i) & 1u);
    return m - (1u << bits);
  }
  // v >= 0 as e = floor(log2(v + 1)) in unary, the leading mantissa bit adaptive, the rest direct.
  std::int64_t exp_golomb(std::uint64_t v, IntegerContexts& c) {
    const int e_in = kDecode ? 0 : std::bit_width(v + 1) - 1;
    int e = 0;
    while (e < kExponentBits && bit(c.exponent[std::size_t(e)], e < e_in ? 1u : 0u)) ++e;
    if (e >= kExponentBits) {
      in_range = false;
      return 0;
    }
    const std::uint64_t rest_in = kDecode ? 0 : (v + 1) - (std::uint64_t(1) << e);
    std::uint64_t rest = 0;
    if (e > 0) {
      const unsigned lead = bit(c.lead[std::size_t(e)], unsigned(rest_in >> (e - 1)) & 1u);
      rest = (std::uint64_t(lead) << (e - 1)) |
             direct(std::uint32_t(rest_in & ((std::uint64_t(1) << (e - 1)) - 1)), e - 1);
    }
    return std::int64_t((std::uint64_t(1) << e) + rest - 1);
  }
  std::int64_t integer(std::int64_t v, IntegerContexts& c) {
    if (!bit(c.zero, v != 0 ? 1u : 0u)) return 0;
    const unsigned negative = bit(c.sign, v < 0 ? 1u : 0u);
    const std::int64_t magnitude = exp_golomb(kDecode ? 0 : std::uint64_t(std::llabs(v) - 1), c) + 1;
    return negative ? -magnitude : magnitude;
  }

  void run(SampleCodeStreams& s) {
    std::array<int, 4> bits{};
    std::array<std::vector<rc::Bit>, 4> trees;
    for (std::size_t a = 0; a < 4; ++a) {
      bits[a] = std::bit_width(std::max<std::uint32_t>(s.palette_size[a], 1) - 1);
      trees[a].resize(std::size_t(1) << (bits[a] + 1));
    }
    std::vector<IntegerContexts> channel(s.k + 1);
    std::vector<std::int64_t> last(s.k + 1, 0);
    for (std::size_t i = 0; i < s.n && in_range; ++i) {
      for (std::size_t a = 0; a < 4; ++a) {
        const std::uint32_t ix = tree(kDecode ? 0 : s.index[4 * i + a], bits[a], trees[a]);
        if constexpr (kDecode) {
          if (ix >= s.palette_size[a]) in_range = false;
          s.index[4 * i + a] = ix;
        }
      }
      for (std::size_t c = 0; c <= s.k; ++c) {
        std::int64_t& slot = c == 0 ? s.mag[i] : s.shape[i * s.k + c - 1];
        const std::int64_t base = s.delta[c] ? last[c] : 0;
        const std::int64_t coded = integer(kDecode ? 0 : slot - base, channel[c]);
        if constexpr (kDecode) {
          slot = base + coded;
          if (slot <= -kMaxSampleCode || slot >= kMaxSampleCode) in_range = false;
        }
        last[c] = slot;
      }
    }
  }
};

int eg_length(std::int64_t v) { return v == 0 ? 1 : 3 + 2 * (std::bit_width(std::uint64_t(std::llabs(v))) - 1); }

}  // namespace

bool prefer_differences(std::span<const std::int64_t> channel, std::size_t stride, std::size_t offset, std::size_t n) {
  std::int64_t values = 0, differences = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t v = channel[i * stride + offset];
    values += eg_length(v);
    differences += eg_length(v - (i ? channel[(i - 1) * stride + offset] : 0));
  }
  return differences < values;
}

std::vector<std::uint8_t> encode_sample_codes(const SampleCodeStreams& s) {
  rc::Encoder enc;
  Traversal<rc::Encoder> t{enc};
  SampleCodeStreams codes = s;  // the traversal is shared with decoding, which writes; encoding only reads
  t.run(codes);
  return enc.finish();
}

bool decode_sample_codes(std::span<const std::uint8_t> bytes, SampleCodeStreams& s) {
  s.index.assign(4 * s.n, 0);
  s.mag.assign(s.n, 0);
  s.shape.assign(s.n * s.k, 0);
  rc::Decoder dec(bytes);
  Traversal<rc::Decoder> t{dec};
  t.run(s);
  return t.in_range && !dec.overrun();
}

}  // namespace specula::codec
