#pragma once
// From a capture directory to scattered BRDF samples (reference chapters 4-5): calibrate (spatial response,
// spectral model, the sphere's circle and placement, light directions), then extract: per light position, HDR
// merge of every band, spectral recovery, division by irradiance and cos(theta_i), rejection of shadowed,
// saturated, bloomed, low-signal and non-linear pixels, and the samples appended to the store light by light.
#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "specula/acquire/calibrate.h"
#include "specula/acquire/capture.h"
#include "specula/acquire/hdr.h"
#include "specula/acquire/spectral.h"
#include "specula/store/store.h"

namespace specula::acquire {

struct PipelineOptions {
  HdrOptions hdr;
  SpectralModel spectral = SpectralModel::delta;
  std::vector<std::string> fit_targets = {"blue", "white"};  ///< as the reference; the rest are held out
  int bloom_px = 2;  ///< pixels within this distance of a saturated one are rejected
  /// Filter captures: the basis the spectra are solved in (B x r on the capture's bands; empty: none), the solve's
  /// ridge (filter_recovery) and the response terms fitted per filter on the targets (fit_filter_response).
  Eigen::MatrixXd filter_basis;
  double filter_ridge = 1e-3;
  int filter_terms = 2;
  /// Filter captures: when not empty, the spectra's second moment (B x B) and the Wiener solve
  /// (filter_wiener_recovery) replace the ridge, with filter k's reading noise filter_noise times its white reading
  /// times, when filter_noise_from_capture, its recorded readings' relative noise over the filters' median
  /// (filter_reading_noise with `sensor`; else 1: every filter as if exposed alike).
  Eigen::MatrixXd filter_prior;
  double filter_noise = 0.002;
  bool filter_noise_from_capture = true;
  SensorNoise sensor;
  std::size_t filter_noise_lights = 8;  ///< light positions filter_reading_noise reads
  /// true: a pixel whose channels are low in signal (below the linear range at the longest exposure) in some but not
  /// all channels is kept, each such channel read at its longest exposure less the bias (sensor.dark_dn), over that
  /// time, at least 0; false: rejected, as the reference discards any value below the range.
  bool keep_dark_channels = true;
};

/// Each filter's relative reading noise as a filter capture recorded it: over the scene pixels of up to `lights`
/// light positions (evenly spaced) whose every filter merged ok or single with a positive rate, the root mean square
/// of sqrt(hdr_rate_variance(rate, that filter's exposure times)) / rate. InputError naming the capture when no
/// pixel qualifies.
Eigen::VectorXd filter_reading_noise(const Capture& capture, const std::filesystem::path& dir, const SensorNoise& noise,
                                     const HdrOptions& o, std::size_t lights = 8);

/// One target's recovered reflectance under both models against its known reflectance (eq 4.8).
struct TargetReport {
  std::string name;
  bool held_out = false;
  Eigen::VectorXd truth, delta, factored;  ///< factored empty when the capture has no LCTF transmission data
  double rms_delta = 0, rms_factored = -1;
  Eigen::VectorXd filters;  ///< a filter capture's recovery (delta and factored are then empty)
  double rms_filters = -1;
};

/// Everything calibration finds.
struct Calibration {
  GreyImage spatial;             ///< S(x, y), 1 at the centre
  SpectralCalibration spectral;  ///< the model used for recovery
  std::vector<TargetReport> targets;
  Circle circle;
  Sphere sphere;
  std::vector<Eigen::Vector3d> light_dirs;  ///< from the sphere's centre, one per light position (arc fit)
  std::vector<double> light_confidence;     ///< 0 where the mirror image had no usable highlight
  double light_distance = 0;                ///< 0: distant lights
};

/// Calibrates from the capture's flat, target, silhouette and mirror images. InputError naming the image for a
/// capture that lacks them or shows nothing usable.
Calibration calibrate_capture(const Capture& capture, const std::filesystem::path& dir, const PipelineOptions& o);

/// Why a (pixel, light) gave no sample.
enum class Reject { shadowed, saturated, bloom, low_signal, nonlinear, count };
inline constexpr std::array<const char*, 5> kRejectNames = {"shadowed", "saturated", "bloom", "low_signal",
                                                            "nonlinear"};

struct ExtractResult {
  std::uint64_t samples = 0;
  std::array<std::uint64_t, std::size_t(Reject::count)> rejected{};
  std::uint64_t sphere_pixels = 0;  ///< pixels wholly on the sphere (edge pixels are never used)
};

/// Pixel p's flat-corrected readings, one per merged channel of `hdr`, into h (resized); the first reason the pixel
/// is unusable (saturated or non-linear in some channel; low in signal in every channel, or in some with
/// o.keep_dark_channels false), or Reject::count when it is usable.
Reject pixel_readings(const std::vector<HdrImage>& hdr, std::size_t p, const GreyImage& spatial,
                      const PipelineOptions& o, Eigen::VectorXd& h);

/// The spectrum of flat-corrected readings h: the calibration's recovery, then, when it has a posterior, the most
/// probable non-negative spectrum (nonnegative_spectrum).
Eigen::VectorXd recover_spectrum(const SpectralCalibration& s, const Eigen::VectorXd& h);

/// Extracts samples light by light into samples `name` of the open transaction (created here; B bands of the
/// capture, units 1/sr relative to the targets' scale). One light's images in memory at a time; checks for
/// interruption between lights.
ExtractResult extract_samples(const Capture& capture, const std::filesystem::path& dir, const Calibration& c,
                              const PipelineOptions& o, store::StoreWriter& out, const std::string& name);

/// Writes the calibration under /acquire/<name> in the transaction (spatial response, recovery matrix, circle,
/// sphere, light directions, target reports) and reads it back.
void write_calibration(store::StoreWriter& out, const std::string& name, const Calibration& c);
Calibration read_calibration(const store::Store& in, const std::string& name);

/// What the HDR stage merged: pixels per status (HdrStatus order) over every light and band.
struct HdrSummary {
  std::size_t lights = 0, bands = 0, pixels = 0;  ///< pixels: width x height x lights
  std::uint64_t valid_pixels = 0;                 ///< pixels whose every band is ok or single
  std::array<std::uint64_t, 5> status{};
};

/// Merges every light's exposure series (of an LCTF capture; InputError for a filter capture) into image "hdr-L<index>"
/// of the transaction (rates in DN/s in every band; a pixel is valid when every band is ok or single); one light in
/// memory at a time, interruptible between lights.
HdrSummary write_hdr_images(const Capture& capture, const std::filesystem::path& dir, const HdrOptions& o,
                            store::StoreWriter& out);

/// The directory's scene/flat/target exposure series of one (kind, light or target, band), merged.
HdrImage merge_series(const Capture& capture, const std::filesystem::path& dir, ImageKind kind, int light, int target,
                      int band, const HdrOptions& o);

}  // namespace specula::acquire
