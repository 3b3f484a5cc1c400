#pragma once
// The .spc codec for spectral BRDF grids (docs/codec-format.md). Every valid cell's spectrum x is split into a
// magnitude m (its band mean) and a shape r = x / m; m is coded as log(1 + m / s) (a dynamic-range mapping
// after Nielsen et al. 2015), r by its k coefficients on an orthonormal spectral basis (learned from a
// database, or fitted to the grid itself). Both are quantised uniformly with steps derived from one error
// target, predicted from their neighbours along phi_d and theta_d (integers, so prediction loses nothing),
// and entropy-coded with zstd. The container is self-describing and ends with a CRC-32 over every byte.
// Format 4 codes scattered measurements instead of a grid: the samples (their exact angles and the same magnitude
// and shape split) and the rule that resamples them (core/brdf_resample.h); decoding resamples them onto the grid.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/core/brdf_resample.h"
#include "specula/core/buffer.h"
#include "specula/store/basis.h"
#include "specula/store/grid.h"

namespace specula::codec {

/// Magic bytes that open a .spc file.
inline constexpr char kSpcMagic[8] = {'S', 'P', 'E', 'C', 'U', 'S', 'P', 'C'};
/// Newest .spc format version this specula reads: 1 (bounded error, predictive), 2 and 3 (transform; 3 adds a step
/// profile over theta_d) and 4 (scattered samples and their resampling rule) are written.
inline constexpr std::uint32_t kSpcVersion = 4;

/// Scattered measurements held by the caller: n samples, angles n x 4 (theta_i, phi_i, theta_o, phi_o, radians)
/// and values n x bands (sample-major) in `units`, value x scale being 1/sr.
struct SpcSampleSet {
  WavelengthGrid wavelengths;
  std::span<const double> angles;
  std::span<const float> values;
  std::string units = "1/sr";
  double scale = 1;
  std::size_t size() const { return angles.size() / 4; }
};

/// k orthonormal spectra (rows) on a wavelength grid, and where they came from.
struct SpcBasis {
  WavelengthGrid wavelengths;
  Eigen::MatrixXd rows;   ///< k x B, orthonormal
  std::string reference;  ///< e.g. "db.h5:pca6" or "self"
  std::size_t k() const { return std::size_t(rows.rows()); }
};

/// The coding basis of a learned store basis: PCA -> the span of its mean and first k - 1 components, NMF ->
/// the span of its first k components, orthonormalised. Throws UsageError unless 1 <= k <= what it holds.
SpcBasis coding_basis(const store::Basis& basis, std::size_t k, const std::string& reference);
/// The largest k coding_basis accepts for `basis`: its components (plus its mean for PCA), at most its bands.
std::size_t coding_basis_max_k(const store::Basis& basis);
/// `basis` extended by the top `extra` eigenvectors of the second moment of what it leaves of the grid's shapes
/// (r minus its projection), so a learned basis can fit a material outside its database; reference gets "+extra".
SpcBasis augment_basis(const SpcBasis& basis, const store::Grid& grid, std::size_t extra);
/// The top k eigenvectors of the uncentred second moment of the grid's shapes r = x / mean(x) over valid
/// cells with a non-zero magnitude. Throws UsageError unless 1 <= k <= bands, InputError if no cell qualifies.
SpcBasis self_basis(const store::Grid& grid, std::size_t k);

/// self_basis of scattered samples: every sample of positive mean counts once (a grid weights each by the cells it
/// fills). UsageError unless 1 <= k <= bands, InputError if no sample qualifies.
SpcBasis self_basis(const SpcSampleSet& samples, std::size_t k);

/// Settings of the bounded method (format 1): every value kept within a stated error of the original.
struct SpcBoundedOptions {
  /// Error target E in (0, 1]: |m' - m| <= E (m + s) for the magnitude and |r'_b - r_k,b| <= E per band for the
  /// shape (r_k: the shape's projection onto the basis).
  double max_error = 0.01;
  /// s of the magnitude mapping in the grid's stored units; 0: a tenth of the median valid magnitude.
  double magnitude_scale = 0;
  int zstd_level = 9;  ///< 1..19
};

/// Settings of the transform method (format 2, or 3 with a grazing factor other than 1): the magnitude and shape
/// channels coded by a 3-D wavelet transform over the grid, with quantisation steps chosen for the rendered appearance
/// rather than a per-value bound (docs/codec-format.md).
struct SpcTransformOptions {
  /// Quantisation step of log(1 + m / s) in the coarsest bands (in (0, 10]); the shape steps are
  /// `shape_step_ratio` times it and finer bands' steps grow by `frequency_factor` per level.
  double step = 0.01;
  double shape_step_ratio = 2;
  double frequency_factor = 1.5;  ///< >= 1; 1 spends bits as mean squared error would
  int levels = 4;                 ///< transform levels, 1..5
  /// Steps near the specular peak times specular_factor (in (0, 1]) at theta_h index 0, rising linearly to the
  /// full step at theta_h index specular_extent (1..90): the small half-angles where a highlight lives.
  double specular_factor = 0.5;
  double specular_extent = 45;
  /// Steps times 1 at theta_d index 0, changing linearly to grazing_factor (in [1/16, 16]) at theta_d index 90. The
  /// lighting suite sees theta_d up to about 53 degrees under its lights, beyond only in the environment, and is as
  /// content with twice the step at grazing theta_d (docs/codec-format.md); 1 writes format 2 as before.
  double grazing_factor = 2;
  /// s of the magnitude mapping in the grid's stored units; 0: a tenth of the median valid magnitude.
  double magnitude_scale = 0;
};

/// Settings of the samples method (format 4): every sample's magnitude and shape quantised as in format 2, its
/// angles kept exactly, and `rule`, with which decoding resamples them onto the grid.
struct SpcSamplesOptions {
  brdf::ResampleOptions rule;
  /// Quantisation step of log(1 + m / s) (in (0, 10]); the shape coefficients' step is shape_step_ratio times it.
  double step = 0.01;
  double shape_step_ratio = 2;
  double magnitude_scale = 0;  ///< s in stored units; 0: a tenth of the median positive sample magnitude
};

/// The grid `samples` resample to under `rule` (cells without support or below the horizon -1): what a format-4
/// file of them decodes to, up to its quantisation. UsageError for bad sizes or options, InputError for no samples.
store::Grid resample_samples(const SpcSampleSet& samples, const brdf::ResampleOptions& rule);

/// What encoding measured.
struct SpcReport {
  std::uint64_t input_bytes = 0;  ///< the grid as float64 (bands x 1,458,000 x 8), as MERL stores RGB
  std::uint64_t output_bytes = 0;
  std::uint64_t valid_cells = 0;
  double magnitude_scale = 0, magnitude_step = 0, shape_step = 0;
  double max_abs_error = 0;           ///< max over valid cells and bands of |x' - x| (scaled units, 1/sr)
  double rms_error = 0;               ///< RMS of x' - x over valid cells and bands (1/sr)
  double max_shape_residual = 0;      ///< max over cells and bands of |r - r_k|: what the basis cannot express
  double max_quantisation_error = 0;  ///< max over cells and bands of |r' - r_k| (at most max_error)
};

/// Encodes `grid` on `basis` (same wavelengths, else InputError naming both) into .spc bytes of format 1; the
/// same bytes for any thread count. Throws UsageError for a bad option.
std::vector<std::uint8_t> encode_spc(const store::Grid& grid, const SpcBasis& basis, const SpcBoundedOptions& options,
                                     SpcReport* report = nullptr, const std::string& source = "");
/// As above in format 2 (the transform method) at options.step.
std::vector<std::uint8_t> encode_spc(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& options,
                                     SpcReport* report = nullptr, const std::string& source = "");
/// Encodes scattered samples on `basis` (same wavelengths, else InputError) into .spc bytes of format 4; the
/// report's errors are against resample_samples of the exact samples. UsageError for a bad option.
std::vector<std::uint8_t> encode_spc(const SpcSampleSet& samples, const SpcBasis& basis,
                                     const SpcSamplesOptions& options, SpcReport* report = nullptr,
                                     const std::string& source = "");
/// A decoded .spc held as its coefficients rather than its bands: per cell the k values a = m' c' (the magnitude
/// folded into the shape coefficients), so the decoded spectrum is x'_b = max(0, sum_j a_j V_jb) in stored units.
struct SpcCoefficients {
  WavelengthGrid wavelengths;
  Eigen::MatrixXd basis;  ///< k x B, the rows V
  double scale = 1;       ///< value x scale is 1/sr
  std::string units, source, reference;
  Buffer<float> values;             ///< kMerlCells x k, cell-major (MERL cell order); 0 in cells without data
  std::vector<std::uint8_t> valid;  ///< kMerlCells; 1 where the cell has data
  std::size_t k() const { return std::size_t(basis.rows()); }
  std::size_t bands() const { return std::size_t(basis.cols()); }
};

/// Decodes .spc bytes to coefficient form; every field and the CRC are checked, and a problem is an InputError
/// starting with `label`.
SpcCoefficients decode_spc_coefficients(std::span<const std::uint8_t> bytes, const std::string& label);
/// The grid of a coefficient form: x'_b = max(0, sum_j a_j V_jb) in valid cells, -1 (no data) elsewhere.
store::Grid expand_spc(const SpcCoefficients& coefficients);
/// expand_spc into out, its storage reused when it holds bands x kMerlCells values already (a search's trials).
void expand_spc(const SpcCoefficients& coefficients, store::Grid& out);
/// Decodes .spc bytes to a grid: expand_spc(decode_spc_coefficients(bytes, label)).
store::Grid decode_spc(std::span<const std::uint8_t> bytes, const std::string& label);
/// The format version of .spc bytes (1 to 4; magic, version and CRC checked as decode_spc does).
std::uint32_t spc_format_version(std::span<const std::uint8_t> bytes, const std::string& label);
/// The basis a .spc file was coded with (checked as decode_spc does).
SpcBasis spc_basis(std::span<const std::uint8_t> bytes, const std::string& label);

/// Writes bytes through a temporary renamed over `path`.
void write_spc_file(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);
/// Reads a whole .spc file (InputError if missing or unreadable).
std::vector<std::uint8_t> read_spc_file(const std::filesystem::path& path);

}  // namespace specula::codec
