// One libFuzzer target per entry function of entries.h, chosen by SPECULA_FUZZ_ENTRY at compile time. A
// specula::Error is a clean rejection; any other exception escapes and libFuzzer reports it with the input.
#include <cstddef>
#include <cstdint>
#include <span>

#include "entries.h"
#include "specula/core/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    specula::fuzz::SPECULA_FUZZ_ENTRY(std::span<const std::uint8_t>(data, size));
  } catch (const specula::Error&) {}
  return 0;
}
