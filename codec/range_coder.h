#pragma once
// An adaptive binary range coder (the carry-propagating coder of LZMA, with 15-bit probabilities) used by .spc
// version 2 (docs/codec-format.md). The decoder reads past the end of its input as zero bytes, so a corrupt or
// truncated stream decodes to wrong values, never out of bounds.
#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

namespace specula::codec::rc {

inline constexpr int kProbBits = 15;
inline constexpr std::uint16_t kProbOne = 1u << kProbBits;
inline constexpr int kAdapt = 5;
inline constexpr std::uint32_t kTop = 1u << 24;

/// The probability (of a 0) of one binary context, adapted after each bit it codes.
struct Bit {
  std::uint16_t p = kProbOne / 2;
};

class Encoder {
 public:
  /// Codes `bit` with context `c` and adapts it.
  void encode(Bit& c, unsigned bit) {
    const std::uint32_t bound = (range_ >> kProbBits) * c.p;
    if (bit == 0) {
      range_ = bound;
      c.p = std::uint16_t(c.p + ((kProbOne - c.p) >> kAdapt));
    } else {
      low_ += bound;
      range_ -= bound;
      c.p = std::uint16_t(c.p - (c.p >> kAdapt));
    }
    while (range_ < kTop) range_ <<= 8, shift_low();
  }
  /// Codes the `n` low bits of `v` (most significant first) with probability 1/2 each.
  void encode_direct(std::uint32_t v, int n) {
    for (int i = n - 1; i >= 0; --i) {
      range_ >>= 1;
      if ((v >> i) & 1u) low_ += range_;
      while (range_ < kTop) range_ <<= 8, shift_low();
    }
  }
  /// Flushes and returns the coded bytes; the encoder is spent.
  std::vector<std::uint8_t> finish() {
    for (int i = 0; i < 5; ++i) shift_low();
    return std::move(out_);
  }

 private:
  void shift_low() {
    if (std::uint32_t(low_) < 0xFF000000u || (low_ >> 32) != 0) {
      const auto carry = std::uint8_t(low_ >> 32);
      std::uint8_t temp = cache_;
      do {
        out_.push_back(std::uint8_t(temp + carry));
        temp = 0xFF;
      } while (--cache_size_ != 0);
      cache_ = std::uint8_t(low_ >> 24);
    }
    ++cache_size_;
    low_ = (low_ & 0x00FFFFFFu) << 8;
  }
  std::uint64_t low_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint8_t cache_ = 0;
  std::uint64_t cache_size_ = 1;
  std::vector<std::uint8_t> out_;
};

class Decoder {
 public:
  explicit Decoder(std::span<const std::uint8_t> in) : in_(in) {
    for (int i = 0; i < 5; ++i) code_ = (code_ << 8) | next();
  }
  /// Decodes one bit with context `c` and adapts it as the encoder did.
  unsigned decode(Bit& c) {
    const std::uint32_t bound = (range_ >> kProbBits) * c.p;
    unsigned bit;
    if (code_ < bound) {
      range_ = bound;
      c.p = std::uint16_t(c.p + ((kProbOne - c.p) >> kAdapt));
      bit = 0;
    } else {
      code_ -= bound;
      range_ -= bound;
      c.p = std::uint16_t(c.p - (c.p >> kAdapt));
      bit = 1;
    }
    while (range_ < kTop) range_ <<= 8, code_ = (code_ << 8) | next();
    return bit;
  }
  /// Decodes `n` bits coded by encode_direct.
  std::uint32_t decode_direct(int n) {
    std::uint32_t v = 0;
    for (int i = 0; i < n; ++i) {
      range_ >>= 1;
      const std::uint32_t bit = code_ >= range_ ? 1u : 0u;
      if (bit) code_ -= range_;
      v = (v << 1) | bit;
      while (range_ < kTop) range_ <<= 8, code_ = (code_ << 8) | next();
    }
    return v;
  }
  /// True when decoding has read more bytes than the stream holds (the stream was truncated or corrupt).
  bool overrun() const { return at_ > in_.size() + 4; }

 private:
  std::uint32_t next() { return at_ < in_.size() ? in_[at_++] : (++at_, 0u); }
  std::span<const std::uint8_t> in_;
  std::size_t at_ = 0;
  std::uint32_t code_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
};

/// One adaptive bit in either direction: an Encoder codes `v` and returns it, a Decoder returns the bit it reads, so
/// one traversal of a format serves both and their contexts cannot disagree.
template <class Coder>
unsigned code_bit(Coder& coder, Bit& c, unsigned v) {
  if constexpr (std::is_same_v<Coder, Decoder>) {
    return coder.decode(c);
  } else {
    coder.encode(c, v);
    return v;
  }
}

/// The `n` low bits of `v` with probability 1/2 each, in either direction as code_bit.
template <class Coder>
std::uint32_t code_direct(Coder& coder, std::uint32_t v, int n) {
  if constexpr (std::is_same_v<Coder, Decoder>) {
    return coder.decode_direct(n);
  } else {
    coder.encode_direct(v, n);
    return v;
  }
}

}  // namespace specula::codec::rc
