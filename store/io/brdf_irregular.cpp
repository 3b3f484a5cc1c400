#include "specula/store/io/brdf_irregular.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <numbers>
#include <string>

#include "specula/core/error.h"

namespace specula::store {
namespace {

// Numbers of a file in order, each with its line; comments from '#' to the end of the line skipped.
class Tokens {
 public:
  explicit Tokens(const std::filesystem::path& path) : path_(path), in_(path) {
    if (!in_) throw InputError(path.string() + ": cannot open");
  }
  bool next(double& v, const char* what) {
    while (pos_ >= line_.size()) {
      if (!std::getline(in_, line_)) return false;
      ++number_;
      if (const auto hash = line_.find('#'); hash != std::string::npos) line_.resize(hash);
      pos_ = 0;
    }
    while (pos_ < line_.size() && std::isspace(static_cast<unsigned char>(line_[pos_]))) ++pos_;
    if (pos_ >= line_.size()) return next(v, what);
    std::size_t end = pos_;
    while (end < line_.size() && !std::isspace(static_cast<unsigned char>(line_[end]))) ++end;
    const std::string token = line_.substr(pos_, end - pos_);
    pos_ = end;
    std::size_t used = 0;
    try {
      v = std::stod(token, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != token.size() || !std::isfinite(v))
      throw InputError(where() + ": '" + token + "' is not a finite number (" + what + ")");
    return true;
  }
  std::string where() const { return path_.string() + " line " + std::to_string(number_); }
  std::size_t line() const { return number_; }
  /// True when the current line holds another token.
  bool more_on_line() {
    while (pos_ < line_.size() && std::isspace(static_cast<unsigned char>(line_[pos_]))) ++pos_;
    return pos_ < line_.size();
  }

 private:
  std::filesystem::path path_;
  std::ifstream in_;
  std::string line_;
  std::size_t pos_ = 0, number_ = 0;
};

}  // namespace

IrregularBrdf read_brdf_irregular(const std::filesystem::path& path) {
  Tokens t(path);
  double v = 0;
  if (!t.next(v, "the number of wavelengths"))
    throw InputError(path.string() + ": empty; expected the number of wavelengths");
  if (v < 1 || v > 1024 || v != std::floor(v))
    throw InputError(t.where() + ": " + std::to_string(v) + " wavelengths; expected a whole number from 1 to 1024");
  const auto bands = std::size_t(v);
  std::vector<double> nm(bands);
  for (auto& w : nm)
    if (!t.next(w, "a wavelength"))
      throw InputError(path.string() + ": ends within the list of " + std::to_string(bands) + " wavelengths");
  IrregularBrdf out;
  out.wavelengths = WavelengthGrid(nm, path.string());
  const std::size_t per = 4 + bands;
  std::vector<double> sample(per);
  // Every sample is one line of 4 + bands numbers, so that a missing or extra value is caught where it is.
  for (;;) {
    double first = 0;
    if (!t.next(first, "an angle")) break;
    const std::size_t line = t.line();
    sample[0] = first;
    std::size_t got = 1;
    while (got < per && t.more_on_line()) {
      t.next(sample[got], got < 4 ? "an angle" : "a BRDF value");
      ++got;
    }
    if (got < per || t.more_on_line()) {
      std::size_t extra = 0;
      double ignored = 0;
      while (t.more_on_line()) {
        t.next(ignored, "a BRDF value");
        ++extra;
      }
      throw InputError(path.string() + " line " + std::to_string(line) + ": sample " + std::to_string(out.size() + 1) +
                       " has " + std::to_string(got + extra) + " numbers; expected " + std::to_string(per) +
                       " (4 angles and " + std::to_string(bands) + " values, one sample per line)");
    }
    for (const std::size_t polar : {std::size_t(0), std::size_t(2)})
      if (sample[polar] < 0 || sample[polar] > std::numbers::pi / 2 + 1e-9)
        throw InputError(t.where() + ": polar angle " + std::to_string(sample[polar]) +
                         " rad is outside [0, pi/2]; angles are in radians");
    for (std::size_t k = 4; k < per; ++k)
      if (sample[k] < 0) throw InputError(t.where() + ": negative BRDF value " + std::to_string(sample[k]));
    out.angles.insert(out.angles.end(), sample.begin(), sample.begin() + 4);
    for (std::size_t k = 4; k < per; ++k) out.values.push_back(float(sample[k]));
  }
  if (out.size() == 0) throw InputError(path.string() + ": holds wavelengths but no samples");
  return out;
}

}  // namespace specula::store
