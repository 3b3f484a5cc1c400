#pragma once
// A capture directory as the reference's rig exports it (docs/capture-format.md): 16-bit PNG files holding the
// camera's 12-bit values, and manifest.json describing every image (kind, light position, band, exposure) and
// the rig. The simulator writes exactly this; the pipeline reads only this, so real captures go through it too.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "specula/acquire/filter_set.h"

namespace specula::acquire {

inline constexpr const char* kCaptureFormat = "specula-capture";
inline constexpr int kCaptureVersion = 3;  ///< 2: captures through a filter wheel; 3: held-out patches

/// What an image shows (holdout: the chart of held-out patches, per channel and exposure).
enum class ImageKind { scene, silhouette, mirror, flat, target, holdout };

/// One image file of a capture.
struct CaptureImage {
  std::string file;  ///< relative to the capture directory
  ImageKind kind = ImageKind::scene;
  int light = -1;   ///< light position index (scene, mirror); -1 otherwise
  int band = -1;    ///< the channel (scene, flat, target): index into Capture::bands, or into Capture::filters for a
                    ///< filter capture; -1 for none (silhouette, mirror)
  int target = -1;  ///< index into Capture::targets (target images)
  double exposure_s = 0;  ///< exposure time
};

/// A diffuse target of known reflectance (one value per band of Capture::bands).
struct CaptureTarget {
  std::string name;
  std::vector<double> reflectance;
};

/// A reflectance patch imaged only to evaluate the recovery, never used by calibration: its known reflectance on the
/// bands and the pixels it covers on the holdout images (u0 <= u < u1, v0 <= v < v1).
struct HoldoutPatch {
  std::string name;
  std::vector<double> reflectance;
  int u0 = 0, v0 = 0, u1 = 0, v1 = 0;
};

/// Ground truth a simulator knows and a real rig does not (absent in real captures).
struct CaptureTruth {
  std::vector<double> sphere_centre;            ///< camera frame, m
  double sphere_radius = 0;                     ///< m
  std::vector<std::vector<double>> light_dirs;  ///< per light position: unit vector from the sphere centre
  std::string material;                         ///< what the sphere is made of
};

/// The manifest of a capture.
struct Capture {
  int width = 0, height = 0;
  int bit_depth = 12;   ///< values in the PNGs are 0 .. 2^bit_depth - 1
  double focal_px = 0;  ///< pinhole intrinsics: focal length and principal point (pixels)
  double cx = 0, cy = 0;
  double sphere_radius_m = 0;            ///< the sample sphere's known radius (0: unknown; the fit then uses 1)
  double light_distance_m = 0;           ///< the arc's radius, light to sphere centre (0: a distant light)
  std::vector<double> bands;             ///< LCTF tuning wavelengths (nm)
  std::vector<double> light_angles_deg;  ///< arc angle of each light position (from the camera, seen from the sphere)
  std::vector<double> light_spectrum_nm, light_spectrum;  ///< the light's relative spectrum, tabulated
  /// The LCTF's tabulated transmission per band (manufacturer's data; optional, the factored model needs it).
  std::vector<std::vector<double>> lctf_nm, lctf_value;
  std::optional<FilterSet> filters;  ///< a filter-wheel capture: one channel per filter; bands are what it recovers
  std::vector<CaptureTarget> targets;
  std::vector<HoldoutPatch> holdout;  ///< patches on the holdout images (format 3; none in older captures)
  std::vector<CaptureImage> images;
  std::optional<CaptureTruth> truth;
  std::string description;
  /// The channels each scene, flat and target series is taken in: the filters' count, or the bands'.
  std::size_t channels() const { return filters ? filters->size() : bands.size(); }
};

/// "scene", "silhouette", ... and back; InputError for an unknown name.
std::string kind_name(ImageKind k);
ImageKind parse_kind(const std::string& name, const std::string& context);

/// Writes dir/manifest.json (through a temporary renamed into place).
void write_manifest(const std::filesystem::path& dir, const Capture& c);
/// Reads and checks dir/manifest.json (versions 1 to 3): InputError naming the file and the field for malformed
/// JSON, a wrong format or newer version, filters that are not transmissions or do not cover the bands,
/// held-out patches off the image or without images in every channel, inconsistent indices, image files that do not
/// exist, or a scene (light, channel) without exposures.
Capture read_manifest(const std::filesystem::path& dir);

}  // namespace specula::acquire
