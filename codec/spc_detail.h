#pragma once
// Internals shared by the .spc codec's files (not installed API): the byte container, the per-cell magnitude
// and shape split both formats use, and the entry points of format 1 (spc_bounded.cpp) and format 2
// (spc_transform.cpp) that spc_container.cpp dispatches to.
#include <Eigen/Core>
#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "specula/codec/spc.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/error.h"

namespace specula::codec::detail {

using brdf::kMerlCells;
using brdf::kMerlPhiD;
using brdf::kMerlThetaD;
using brdf::kMerlThetaH;
constexpr std::size_t kSlab = std::size_t(kMerlThetaD) * kMerlPhiD;  // cells per theta_h index
constexpr std::uint32_t kMaxBands = 1024;
constexpr std::uint32_t kMaxString = 1 << 16;

inline void put_bytes(std::vector<std::uint8_t>& out, const void* p, std::size_t n) {
  const std::size_t at = out.size();
  out.resize(at + n);  // resize and copy: GCC 12 warns falsely (-Wstringop-overflow) on a growing range insert
  if (n) std::memcpy(out.data() + at, p, n);
}
template <class T>
inline void put(std::vector<std::uint8_t>& out, T v) {
  put_bytes(out, &v, sizeof v);  // little-endian hosts only (checked below)
}
inline void put_string(std::vector<std::uint8_t>& out, const std::string& s) {
  put(out, std::uint32_t(std::min<std::size_t>(s.size(), kMaxString)));
  put_bytes(out, s.data(), std::min<std::size_t>(s.size(), kMaxString));
}
static_assert(std::endian::native == std::endian::little, ".spc I/O assumes a little-endian host");

/// Bounds-checked little-endian reading of a .spc byte range; errors name `label`.
class Reader {
 public:
  Reader(std::span<const std::uint8_t> b, const std::string& label) : b_(b), label_(label) {}
  template <class T>
  T get(const char* what) {
    T v;
    std::memcpy(&v, take(sizeof v, what), sizeof v);
    return v;
  }
  const std::uint8_t* take(std::size_t n, const char* what) {
    if (n > b_.size() - at_)
      throw InputError(label_ + ": .spc file is truncated: " + what + " needs " + std::to_string(n) +
                       " bytes at byte " + std::to_string(at_) + ", " + std::to_string(b_.size() - at_) + " remain");
    const std::uint8_t* p = b_.data() + at_;
    at_ += n;
    return p;
  }
  std::string string(const char* what) {
    const auto n = get<std::uint32_t>(what);
    if (n > kMaxString) throw InputError(label_ + ": .spc field " + what + " claims " + std::to_string(n) + " bytes");
    const auto* p = take(n, what);
    return {reinterpret_cast<const char*>(p), n};
  }
  std::size_t at() const { return at_; }

 private:
  std::span<const std::uint8_t> b_;
  const std::string& label_;
  std::size_t at_ = 0;
};

// x'_b = max(0, sum_j a_j V_jb): negatives clipped to 0, since a negative value would read as "no data".
inline void expand_cell(const Eigen::MatrixXd& basis, const float* a, float* out, std::size_t out_stride) {
  const auto k = basis.rows(), bands = basis.cols();
  for (Eigen::Index b = 0; b < bands; ++b) {
    double x = 0;
    for (Eigen::Index j = 0; j < k; ++j) x += double(a[j]) * basis(j, b);
    out[std::size_t(b) * out_stride] = float(std::max(0.0, x));
  }
}

// The k x B basis stored as T (double in format 1, float in format 2), every value finite.
template <class T>
inline Eigen::MatrixXd read_basis(Reader& r, std::size_t k, std::size_t bands, const std::string& label) {
  std::vector<T> v(k * bands);
  std::memcpy(v.data(), r.take(sizeof(T) * v.size(), "basis"), sizeof(T) * v.size());
  Eigen::MatrixXd m(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(bands));
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t b = 0; b < bands; ++b) {
      if (!std::isfinite(v[j * bands + b])) throw InputError(label + ": .spc basis holds a non-finite value");
      m(Eigen::Index(j), Eigen::Index(b)) = double(v[j * bands + b]);
    }
  return m;
}

/// Magic, version and CRC of a .spc file of any version; returns the version.
std::uint32_t check_container(std::span<const std::uint8_t> bytes, const std::string& label);
/// The header's band count and k, checked (both formats).
std::pair<std::uint32_t, std::uint32_t> read_shape(Reader& r, const std::string& label);
/// The header's scale and magnitude scale s, each finite and positive (InputError naming the field otherwise).
std::pair<double, double> read_scales(Reader& r, const std::string& label);
/// What formats 2 to 4 write first, as check_container, read_shape and read_scales read it: magic, version, bands,
/// k, scale and magnitude scale s.
void put_head(std::vector<std::uint8_t>& out, std::uint32_t version, std::size_t bands, std::size_t k, double scale,
              double s);
/// What they write after the wavelengths: the basis's first k rows (float32, k x bands), then the units, the
/// source and the basis's reference.
void put_basis_and_labels(std::vector<std::uint8_t>& out, const SpcBasis& basis, std::size_t k, std::size_t bands,
                          const std::string& units, const std::string& source);
/// The wavelengths of a header, InputError naming `label` when they are not a valid grid.
WavelengthGrid checked_wavelengths(std::vector<double> wl, const std::string& label);
/// Per cell whether it has data (every band >= 0) and its magnitude, the band mean (0 without data); InputError on
/// a non-finite value. Returns the number of cells with data.
std::uint64_t magnitudes(const store::Grid& grid, std::vector<float>& mag, std::vector<std::uint8_t>& valid);
/// s of the magnitude mapping: `given`, or when 0 a tenth of the median positive magnitude (1 if there is none).
double magnitude_scale(const std::vector<float>& mag, const std::vector<std::uint8_t>& valid, double given);
/// raw compressed as one zstd frame at `level` (LibraryError on failure).
std::vector<std::uint8_t> zstd_compress(const std::vector<std::uint8_t>& raw, int level);
/// A zstd frame of `size` bytes decompressed into out, whose size the caller has set to what the header promises;
/// InputError naming `label` and section `what` when the frame does not hold exactly that.
void zstd_decompress(const std::uint8_t* src, std::size_t size, std::vector<std::uint8_t>& out,
                     const std::string& label, const char* what);
/// The CRC-32 (zlib) of bytes.
std::uint32_t crc32_of(std::span<const std::uint8_t> bytes);

/// Format 1: encodes; decodes a checked container (header only: basis and strings, values empty).
std::vector<std::uint8_t> encode_bounded(const store::Grid& grid, const SpcBasis& basis, const SpcBoundedOptions& o,
                                         SpcReport* report, const std::string& source);
SpcCoefficients decode_bounded(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only);

/// Formats 2 and 3: encodes; decodes a checked container (header only: basis and strings, values empty).
std::vector<std::uint8_t> encode_transform(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o,
                                           SpcReport* report, const std::string& source);
SpcCoefficients decode_transform(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only);

/// A coding quantised at any step, whose decoding a target search (spc_target.cpp) judges step by step.
class StepCoder {
 public:
  virtual ~StepCoder() = default;
  /// The finest step the codes allow.
  virtual double finest_step() const = 0;
  /// The grid a file coded at `step` decodes to, into out (its storage reused when it has the size already).
  virtual void decoded(double step, store::Grid& out) const = 0;
  /// The file at `step`, with what it measures when asked.
  virtual std::vector<std::uint8_t> code(double step, SpcReport* report, const std::string& source) const = 0;
};

/// A grid transformed once for format 2 and then quantised at any step: what a step search trials.
class TransformModel final : public StepCoder {
 public:
  /// Checks the options (UsageError) and the basis (InputError) and transforms the grid's channels.
  TransformModel(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& options);
  ~TransformModel() override;
  /// The finest step (of the options' ratios) whose codes all stay below 2^27.
  double finest_step() const override;
  void decoded(double step, store::Grid& out) const override;
  /// The file at `step`, with what it measures against the grid when asked.
  std::vector<std::uint8_t> code(double step, SpcReport* report, const std::string& source) const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Format 4: the samples quantised at any step (their magnitude and shape split once), judged against `reference`
/// (resample_samples of the exact samples; the caller keeps samples, basis and reference alive).
class SamplesModel final : public StepCoder {
 public:
  /// Checks the options (UsageError) and the basis and samples (InputError) and splits every sample.
  SamplesModel(const SpcSampleSet& samples, const SpcBasis& basis, const SpcSamplesOptions& options,
               const store::Grid& reference);
  ~SamplesModel() override;
  /// The finest step whose codes all stay below 2^27.
  double finest_step() const override;
  void decoded(double step, store::Grid& out) const override;
  /// The file at `step`, with its errors against the reference when asked.
  std::vector<std::uint8_t> code(double step, SpcReport* report, const std::string& source) const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Format 4: decodes a checked container (header only: basis and strings, values empty).
SpcCoefficients decode_samples(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only);

}  // namespace specula::codec::detail
