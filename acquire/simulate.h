#pragma once
// A simulator of the reference's rig (§4.1, §5.1): a pinhole camera (12-bit monochrome, exposure bracketing, shot
// and read noise, saturation, vignetting) behind a liquid-crystal tunable filter, a sphere of an analytic
// spectral BRDF slightly off the optical axis, a tungsten-halogen point light moved on an arc. It writes a capture
// directory (acquire/capture.h) with scene, backlit silhouette, mirror-sphere, flat-field and diffuse-target
// images, and the ground truth in the manifest.
#include <filesystem>
#include <string>
#include <vector>

#include <memory>
#include <optional>

#include "specula/acquire/capture.h"
#include "specula/acquire/filter_set.h"
#include "specula/acquire/scan.h"
#include "specula/core/brdf_models.h"
#include "specula/store/cube.h"
#include "specula/store/grid.h"

namespace specula::acquire {

/// The LCTF passband of each tuning wavelength.
enum class Passband { delta, gaussian };

struct SimulatorOptions {
  std::string material = "red-plastic";     ///< a name of core/brdf_materials.h (ignored when grid is set)
  std::shared_ptr<const store::Grid> grid;  ///< a spectral grid to image instead (MERL layout); material names it
  int width = 256, height = 256;
  ScanRig rig;                ///< geometry; rig.sphere_px sets the sphere's size on the image
  std::vector<double> bands;  ///< tuning wavelengths (nm); empty: 420 to 720 every 10
  std::vector<double> exposures_s = {1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 3.0, 8.0};  ///< 100 us to 8 s
  Passband passband = Passband::gaussian;
  double fwhm_blue_nm = 10, fwhm_red_nm = 20;  ///< Gaussian FWHM at 420 nm, growing linearly to this at 720 nm
  double light_kelvin = 3200;                  ///< tungsten-halogen, as a blackbody
  double brightness = 20000;    ///< DN/s from a white Lambertian facing light and camera in the strongest band
  double read_noise_dn = 1.5;   ///< Gaussian read noise (DN)
  double electrons_per_dn = 4;  ///< shot noise: Poisson in electrons (approximated as Gaussian)
  double dark_dn = 8;           ///< offset every pixel carries (bias)
  double vignetting = 0.25;     ///< fraction of light lost at the image corner (S = 1 - v (r / r_corner)^2)
  bool noise = true;
  /// A filter wheel instead of the LCTF: one channel per filter, its exposures (and the flats' and targets') the
  /// bracket above divided by the filter's white signal relative to the LCTF's strongest band.
  std::optional<FilterSet> filters;
  double lctf_peak = 0.35;  ///< the LCTF's peak transmission, the scale filter captures are exposed against
  /// Held-out reflectance patches (a table, linear between its wavelengths, constant beyond them) imaged as a chart
  /// in the targets' place through every channel with the scene's bracket (holdout_chart lays them out); the
  /// manifest records them, calibration never uses them.
  std::optional<store::Collection> holdout;
  unsigned seed = 1;
  int threads_hint = 0;  ///< unused by results: the images do not depend on the thread count
};

/// UsageError stating the rule for a bad option (sizes, bands, exposures, noise, an unknown material, a sphere
/// that does not fit on the image).
void check_simulator(const SimulatorOptions& o);

/// Simulates every image into `dir` (created; must be empty or absent) and writes its manifest with the truth.
/// Deterministic for a seed, whatever the thread count. Returns the manifest.
Capture simulate_capture(const SimulatorOptions& o, const std::filesystem::path& dir);

/// How a grid is read between its cell centres: the cell MERL's BRDFRead.cpp reads, or trilinear in MERL index space
/// (sqrt theta_h, theta_d, phi_d; phi_d wraps at pi by reciprocity) between the 8 surrounding centres.
enum class GridLookup { nearest, trilinear };

/// A spectral grid as an analytic-style model on `target` wavelengths, value * scale, linearly interpolated between
/// the grid's bands and held constant beyond. nearest: as BRDFRead.cpp (no data counts as 0); trilinear: corners
/// without data left out and the others' weights renormalised (0 when none has data).
std::unique_ptr<brdf::SpectralModel> grid_material(std::shared_ptr<const store::Grid> grid,
                                                   const WavelengthGrid& target,
                                                   GridLookup lookup = GridLookup::nearest);

/// The simulated camera's relative quantum efficiency (with the optics' transmission) at `nm`.
double camera_quantum_efficiency(double nm);

/// The relative spectral response R_j on `nm` (rows: bands, or filters) for the options' passband model or
/// filters and camera (transmission times the camera's quantum efficiency), as the simulator uses it.
std::vector<std::vector<double>> simulated_response(const SimulatorOptions& o, const std::vector<double>& nm);

}  // namespace specula::acquire
