// libFuzzer target: parse_envi_header must either return a consistent header or throw specula::Error with a
// one-line message. Any other exception, a crash, a sanitizer report or a broken invariant is a finding.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "specula/core/error.h"
#include "specula/store/io/envi.h"

namespace {

void check(bool ok) {
  if (!ok) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const specula::store::EnviHeader h = specula::store::parse_envi_header(text, "fuzz.hdr");
    check(h.samples > 0 && h.lines > 0 && h.bands > 0);
    check(h.data_type == 1 || h.data_type == 2 || h.data_type == 3 || h.data_type == 4 || h.data_type == 5 ||
          h.data_type == 12);
    check(h.byte_order == 0 || h.byte_order == 1);
    check(h.wavelength.empty() || h.wavelength.size() == h.bands);
    check(h.fwhm.empty() || h.fwhm.size() == h.bands);
    check(h.band_names.empty() || h.band_names.size() == h.bands);
    for (std::size_t i = 1; i < h.wavelength.size(); ++i) check(h.wavelength[i] > h.wavelength[i - 1]);
    unsigned __int128 bytes = static_cast<unsigned __int128>(h.samples) * h.lines * h.bands * 8;
    check(bytes <= (static_cast<unsigned __int128>(1) << 43));
  } catch (const specula::Error& e) {
    const std::string what = e.what();
    check(what.rfind("fuzz.hdr", 0) == 0);
    check(what.find('\n') == std::string::npos && what.find('\r') == std::string::npos);
  }
  return 0;
}
