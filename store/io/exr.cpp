#include "specula/store/io/exr.h"

#include <Iex.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>
#include <half.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

namespace specula::store {
namespace fs = std::filesystem;

namespace {

constexpr const char* kLayoutVersionAttribute = "spectralLayoutVersion";
constexpr const char* kLayoutVersion = "1.0";
constexpr const char* kEmissiveUnitsAttribute = "emissiveUnits";
constexpr const char* kEmissiveUnits = "W.m^-2.sr^-1";

std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  std::replace(text.begin(), text.end(), '\r', ' ');
  return text;
}

// Runs OpenEXR calls that read `path`; the library's complaints about the file become InputError.
template <class F>
auto exr_reading(const fs::path& path, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const Iex::BaseExc& e) {
    throw InputError(path.string() + ": cannot read OpenEXR file: " + one_line(e.what()));
  }
}

// Runs OpenEXR calls that write `path`; any library failure becomes LibraryError.
template <class F>
auto exr_writing(const fs::path& path, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const Iex::BaseExc& e) {
    throw LibraryError(path.string() + ": OpenEXR failed to write: " + one_line(e.what()));
  }
}

struct SpectralChannel {
  std::string name;
  bool reflective = false;
  double nm = 0.0;
};

double power_of_ten(int k) { return k >= 0 ? std::pow(10.0, k) : 1.0 / std::pow(10.0, -k); }

std::optional<int> si_prefix_exponent(std::string_view prefix) {
  static constexpr std::array<std::pair<std::string_view, int>, 19> table{{
      {"", 0},   {"Y", 24}, {"Z", 21},  {"E", 18},        {"P", 15},        {"T", 12}, {"G", 9},
      {"M", 6},  {"k", 3},  {"h", 2},   {"da", 1},        {"d", -1},        {"c", -2}, {"m", -3},
      {"u", -6}, {"n", -9}, {"p", -12}, {"\xc2\xb5", -6}, {"\xce\xbc", -6},
  }};
  for (const auto& [text, exponent] : table)
    if (text == prefix) return exponent;
  return std::nullopt;
}

// Parses "<number><SI prefix>(m|Hz)" with ',' or '.' as decimal separator and an optional exponent, e.g.
// "380,000000nm", "0.55um", "5.45e14Hz"; returns the wavelength in nm, or nothing when `s` is not of this form.
std::optional<double> parse_wavelength_nm(std::string_view s) {
  auto digit = [&](std::size_t k) { return k < s.size() && s[k] >= '0' && s[k] <= '9'; };
  std::size_t i = 0, digits = 0;
  for (; digit(i); ++i) ++digits;
  if (i < s.size() && (s[i] == ',' || s[i] == '.')) {
    ++i;
    for (; digit(i); ++i) ++digits;
  }
  if (digits == 0) return std::nullopt;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    std::size_t k = i + 1;
    if (k < s.size() && (s[k] == '+' || s[k] == '-')) ++k;
    if (digit(k)) {
      for (i = k; digit(i); ++i) {}
    }
  }
  std::string number(s.substr(0, i));
  std::replace(number.begin(), number.end(), ',', '.');
  double value = 0.0;
  const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (ec != std::errc() || end != number.data() + number.size()) return std::nullopt;

  const std::string_view unit = s.substr(i);
  const bool hertz = unit.ends_with("Hz");
  if (!hertz && !unit.ends_with("m")) return std::nullopt;
  const auto exponent = si_prefix_exponent(unit.substr(0, unit.size() - (hertz ? 2 : 1)));
  if (!exponent) return std::nullopt;
  if (hertz) return 299792458.0 * 1e9 / (value * power_of_ten(*exponent));
  return value * power_of_ten(*exponent + 9);
}

// Recognises "T.<wavelength>" (reflective) and "S0.<wavelength>" (emissive, first Stokes component).
std::optional<SpectralChannel> parse_spectral_channel(std::string_view name) {
  SpectralChannel channel{std::string(name), false, 0.0};
  std::string_view rest;
  if (name.starts_with("T.")) {
    channel.reflective = true;
    rest = name.substr(2);
  } else if (name.starts_with("S0.")) {
    rest = name.substr(3);
  } else {
    return std::nullopt;
  }
  const auto nm = parse_wavelength_nm(rest);
  if (!nm) return std::nullopt;
  channel.nm = *nm;
  return channel;
}

// "<int>,<frac>" as the reference implementation writes it (six decimals), or more digits when six would not
// read back as exactly `nm`.
std::string format_wavelength(double nm) {
  char buffer[128];
  std::snprintf(buffer, sizeof buffer, "%.6f", nm);
  std::string text = buffer;
  double back = 0.0;
  std::from_chars(text.data(), text.data() + text.size(), back);
  if (back != nm) {
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, nm, std::chars_format::fixed);
    text.assign(buffer, result.ptr);
    if (text.find('.') == std::string::npos) text += ".0";
  }
  std::replace(text.begin(), text.end(), '.', ',');
  return text;
}

std::string channel_name(bool reflective, double nm) {
  return (reflective ? "T." : "S0.") + format_wavelength(nm) + "nm";
}

void check_dimensions(const fs::path& path, std::size_t width, std::size_t height) {
  if (width == 0 || height == 0 || width > INT_MAX || height > INT_MAX)
    throw UsageError(path.string() + ": OpenEXR image size must be between 1 and 2^31-1 pixels per side, got " +
                     std::to_string(width) + " x " + std::to_string(height));
}

// Writes `header` and the pixels of `frame` to `path` atomically, checking the stream after OpenEXR closes it
// (OutputFile's destructor swallows errors).
void write_exr(const fs::path& path, const Imf::Header& header, const Imf::FrameBuffer& frame, int height) {
  AtomicOutput out(path);
  std::ofstream os(out.temp_path(), std::ios::binary | std::ios::trunc);
  if (!os) throw LibraryError(out.temp_path().string() + ": cannot create file: " + std::strerror(errno));
  exr_writing(path, [&] {
    Imf::StdOFStream stream(os, out.temp_path().c_str());
    Imf::OutputFile file(stream, header);
    file.setFrameBuffer(frame);
    file.writePixels(height);
  });
  os.close();
  if (!os) throw LibraryError(path.string() + ": cannot write OpenEXR file: " + std::strerror(errno));
  out.commit();
}

}  // namespace

Cube read_spectral_exr(const fs::path& path) {
  return exr_reading(path, [&] {
    Imf::InputFile file(path.c_str());
    const Imf::Header& header = file.header();

    std::vector<SpectralChannel> reflective, emissive;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
      auto channel = parse_spectral_channel(it.name());
      if (!channel) continue;
      if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
        throw InputError(path.string() + ": spectral channel " + channel->name +
                         " is subsampled, which spectral EXR images do not allow");
      if (!(channel->nm > 0.0) || !std::isfinite(channel->nm))
        throw InputError(path.string() + ": spectral channel " + channel->name +
                         " names a wavelength that is not positive and finite");
      (channel->reflective ? reflective : emissive).push_back(std::move(*channel));
    }
    const bool is_reflective = !reflective.empty();
    std::vector<SpectralChannel>& channels = is_reflective ? reflective : emissive;
    if (channels.empty())
      throw InputError(path.string() +
                       ": no spectral channels (T.<wavelength>nm or S0.<wavelength>nm); not a spectral EXR "
                       "in the layout of Fichet et al. 2021");
    std::sort(channels.begin(), channels.end(),
              [](const SpectralChannel& a, const SpectralChannel& b) { return a.nm < b.nm; });
    for (std::size_t b = 1; b < channels.size(); ++b)
      if (channels[b].nm == channels[b - 1].nm)
        throw InputError(path.string() + ": channels " + channels[b - 1].name + " and " + channels[b].name +
                         " name the same wavelength");

    const Imath::Box2i window = header.dataWindow();
    const long long width = static_cast<long long>(window.max.x) - window.min.x + 1;
    const long long height = static_cast<long long>(window.max.y) - window.min.y + 1;
    if (width <= 0 || height <= 0) throw InputError(path.string() + ": empty OpenEXR data window");
    if (static_cast<double>(width) * static_cast<double>(height) * static_cast<double>(channels.size()) > 0x1p32)
      throw InputError(path.string() + ": data window " + std::to_string(width) + " x " + std::to_string(height) +
                       " with " + std::to_string(channels.size()) +
                       " bands exceeds 2^32 samples; the header is probably corrupt");

    Cube cube;
    std::vector<double> nm;
    for (const auto& c : channels) nm.push_back(c.nm);
    cube.wavelengths = WavelengthGrid(std::move(nm), path.string());
    cube.resize(static_cast<std::size_t>(height), static_cast<std::size_t>(width), channels.size());

    const std::size_t x_stride = sizeof(float) * cube.bands;
    const std::size_t y_stride = x_stride * cube.width;
    Imf::FrameBuffer frame;
    for (std::size_t b = 0; b < channels.size(); ++b)
      frame.insert(channels[b].name, Imf::Slice::Make(Imf::FLOAT, cube.data.data() + b, window, x_stride, y_stride));
    // A mask travels as the alpha channel "A" (0 = masked), which spectral readers ignore.
    std::vector<float> alpha;
    if (header.channels().findChannel("A")) {
      alpha.assign(cube.height * cube.width, 1.0f);
      frame.insert("A", Imf::Slice::Make(Imf::FLOAT, alpha.data(), window, sizeof(float), sizeof(float) * cube.width));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    if (!alpha.empty()) {
      cube.mask.resize(alpha.size());
      for (std::size_t p = 0; p < alpha.size(); ++p) cube.mask[p] = alpha[p] > 0.5f ? 1 : 0;
    }

    cube.units = is_reflective ? "reflectance" : "radiance";
    cube.provenance.source_file = path.string();
    cube.provenance.importer = "exr";
    return cube;
  });
}

std::vector<float> read_exr_rgb(const fs::path& path, std::size_t& width, std::size_t& height) {
  return exr_reading(path, [&] {
    Imf::InputFile file(path.c_str());
    const Imf::Header& header = file.header();
    for (const char* c : {"R", "G", "B"})
      if (!header.channels().findChannel(c))
        throw InputError(path.string() + ": no '" + c + "' channel; an RGB EXR needs R, G and B");
    const Imath::Box2i window = header.dataWindow();
    const long long w = static_cast<long long>(window.max.x) - window.min.x + 1;
    const long long h = static_cast<long long>(window.max.y) - window.min.y + 1;
    if (w <= 0 || h <= 0 || double(w) * double(h) > 0x1p28)
      throw InputError(path.string() + ": OpenEXR data window " + std::to_string(w) + " x " + std::to_string(h) +
                       " is empty or too large for an environment map");
    width = std::size_t(w);
    height = std::size_t(h);
    std::vector<float> rgb(3 * width * height);
    Imf::FrameBuffer frame;
    const char* names[3] = {"R", "G", "B"};
    for (std::size_t c = 0; c < 3; ++c)
      frame.insert(names[c],
                   Imf::Slice::Make(Imf::FLOAT, rgb.data() + c, window, 3 * sizeof(float), 3 * sizeof(float) * width));
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    for (std::size_t i = 0; i < rgb.size(); ++i)
      if (!std::isfinite(rgb[i]))
        throw InputError(path.string() + ": pixel (" + std::to_string(i / 3 % width) + ", " +
                         std::to_string(i / 3 / width) + ") holds a non-finite value");
    return rgb;
  });
}

bool exr_is_spectral(const fs::path& path) {
  return exr_reading(path, [&] {
    Imf::InputFile file(path.c_str());
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it)
      if (parse_spectral_channel(it.name())) return true;
    return false;
  });
}

void write_spectral_exr(const fs::path& path, const Cube& cube) {
  check_dimensions(path, cube.width, cube.height);
  if (cube.bands == 0 || cube.wavelengths.size() != cube.bands ||
      cube.data.size() != cube.height * cube.width * cube.bands)
    throw UsageError(path.string() + ": inconsistent cube (" + std::to_string(cube.bands) + " bands, " +
                     std::to_string(cube.wavelengths.size()) + " wavelengths, " + std::to_string(cube.data.size()) +
                     " values for " + std::to_string(cube.width) + " x " + std::to_string(cube.height) + " pixels)");
  const bool reflective = cube.units == "reflectance";
  const std::size_t x_stride = sizeof(float) * cube.bands;
  const std::size_t y_stride = x_stride * cube.width;
  exr_writing(path, [&] {
    Imf::Header header(static_cast<int>(cube.width), static_cast<int>(cube.height));
    header.compression() = Imf::ZIP_COMPRESSION;
    header.insert(kLayoutVersionAttribute, Imf::StringAttribute(kLayoutVersion));
    if (!reflective) header.insert(kEmissiveUnitsAttribute, Imf::StringAttribute(kEmissiveUnits));
    Imf::FrameBuffer frame;
    for (std::size_t b = 0; b < cube.bands; ++b) {
      const std::string name = channel_name(reflective, cube.wavelengths[b]);
      header.channels().insert(name, Imf::Channel(Imf::FLOAT));
      char* base = const_cast<char*>(reinterpret_cast<const char*>(cube.data.data() + b));
      frame.insert(name, Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
    }
    std::vector<float> alpha;
    if (!cube.mask.empty()) {
      alpha.resize(cube.mask.size());
      for (std::size_t p = 0; p < alpha.size(); ++p) alpha[p] = cube.mask[p] ? 1.0f : 0.0f;
      header.channels().insert("A", Imf::Channel(Imf::FLOAT));
      frame.insert("A", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(alpha.data()), sizeof(float),
                                   sizeof(float) * cube.width));
    }
    write_exr(path, header, frame, static_cast<int>(cube.height));
  });
}

void write_exr_rgb(const fs::path& path, std::size_t width, std::size_t height, std::span<const float> rgb) {
  check_dimensions(path, width, height);
  if (rgb.size() != 3 * width * height)
    throw UsageError(path.string() + ": expected " + std::to_string(3 * width * height) + " RGB values for a " +
                     std::to_string(width) + " x " + std::to_string(height) + " image, got " +
                     std::to_string(rgb.size()));
  std::vector<Imath::half> halves(rgb.begin(), rgb.end());
  exr_writing(path, [&] {
    Imf::Header header(static_cast<int>(width), static_cast<int>(height));
    header.compression() = Imf::ZIP_COMPRESSION;
    Imf::FrameBuffer frame;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
      header.channels().insert(names[c], Imf::Channel(Imf::HALF));
      char* base = reinterpret_cast<char*>(halves.data() + c);
      frame.insert(names[c], Imf::Slice(Imf::HALF, base, 3 * sizeof(Imath::half), 3 * sizeof(Imath::half) * width));
    }
    write_exr(path, header, frame, static_cast<int>(height));
  });
}

}  // namespace specula::store
