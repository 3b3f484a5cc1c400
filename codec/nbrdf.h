#pragma once
// Neural BRDFs (Sztrajman et al. 2021) on the MERL grid: the 6 -> 21 -> 21 -> 3 perceptron (ReLU, ReLU, then
// exp(x) - 1) evaluated at every cell centre from the half vector and the difference vector (phi_h = 0), and
// the import of such networks into a store as spectral grids (Appendix A uplift, codec/uplift.h).
#include <Eigen/Core>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "specula/codec/merl.h"
#include "specula/codec/uplift.h"
#include "specula/store/io/nbrdf.h"
#include "specula/store/store.h"

namespace specula::codec {

/// The network's RGB BRDF (1/sr) for half vector h and difference vector d (unit vectors in the local frame).
Eigen::Vector3d nbrdf_value(const store::NbrdfWeights& w, const Eigen::Vector3d& h, const Eigen::Vector3d& d);

/// What evaluating a network on the grid did.
struct NbrdfGridReport {
  std::size_t cells = 0;    ///< cells above the horizon, evaluated
  std::size_t clamped = 0;  ///< channel values below 0 (exp(x) - 1 > -1) set to 0, which MERL would read as no data
};
/// The network at every MERL cell centre with both directions above the horizon (others: no data), as an RGB
/// MERL BRDF; on all threads, independent of their number.
MerlBrdf nbrdf_to_merl(const store::NbrdfWeights& w, NbrdfGridReport* report = nullptr);

/// How NBRDF files become store grids.
struct NbrdfImportOptions {
  std::string name;            ///< grid name for a single input; empty: the file's stem
  WavelengthGrid wavelengths;  ///< bands of the uplifted grids
  Eigen::VectorXd illuminant;  ///< SPD on `wavelengths` under which the RGB was seen (rgb_weights())
  double alpha = kDefaultUpliftAlpha;
};

/// The .h5 files `inputs` name: files as given, directories expanded to their .h5 files in name order;
/// InputError naming an input that is missing or a directory holding no .h5 file.
std::vector<std::filesystem::path> nbrdf_files(std::span<const std::filesystem::path> inputs);

/// Reads, evaluates and uplifts (non-negative, eq A.3) every file of `files` into `writer` as grids, one per
/// file; returns one line per grid for the user. InputError naming the file for bad weights, UsageError when a
/// name is given for several files. Nothing is written before every file has been read.
std::vector<std::string> import_nbrdf(store::StoreWriter& writer, std::span<const std::filesystem::path> files,
                                      const NbrdfImportOptions& options);

}  // namespace specula::codec
