#pragma once
// Projection of spectra onto a learned basis (reference §7.3, eqs 7.2-7.3; §7.4): onto the first k principal
// components of a PCA basis, about its mean, or by exact non-negative least squares onto all components of an
// NMF basis; reconstruction from the coefficients, and the error measures reported for it. The one projector of
// specula: `specula project`, `specula coefficients`, the viewer and specula.project() all call it.
// Placement: stats, beside pca_project/pca_reconstruct (eqs 7.2-7.3), which it calls. The NMF path solves with the
// core NNLS (core/nnls.h) rather than anything in nmf, so stats and nmf stay siblings and the dependency direction
// core <- store <- stats holds; nmf itself only learns bases.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "specula/core/colour.h"
#include "specula/core/nnls.h"
#include "specula/core/wavelengths.h"
#include "specula/store/basis.h"
#include "specula/store/cube.h"

namespace specula::stats {

enum class BasisMethod { pca, nmf };

/// The method of `basis` (called `name` in messages; empty: "the basis"): InputError unless its method is "nmf",
/// or "pca" with a mean of one value per band.
BasisMethod basis_method(const store::Basis& basis, const std::string& name = "");

/// How rms and max_error of ProjectionError are defined (as `specula project --json` reports it).
inline constexpr const char* kProjectionErrorDefinition =
    "rms = sqrt(mean over valid pixels of ||x - x'||^2 / B) (per-band root-mean-square error); "
    "max_error = largest per-pixel ||x - x'||_2 over bands";

/// Reconstruction errors of a set of spectra summed as kProjectionErrorDefinition defines them.
struct ProjectionError {
  std::uint64_t count = 0;  ///< spectra added
  double sum_sq = 0;        ///< sum of their squared L2 errors ||x - x'||_2^2
  double max_error = 0;     ///< largest L2 error

  /// Adds one spectrum whose squared L2 error over bands is `squared`.
  void add(double squared);
  /// Adds the spectra of `other` (e.g. another block's), as if each had been added here.
  void merge(const ProjectionError& other);
  /// sqrt(sum_sq / (count * bands)); NaN when nothing was added.
  double rms(std::size_t bands) const;
};

/// Squared L2 errors ||x_i - x'_i||^2 of the rows of `spectra` and `reconstruction` (both n x B) into `squared` (n).
void squared_errors(const Eigen::Ref<const RowMatrixXd>& spectra, const Eigen::Ref<const RowMatrixXd>& reconstruction,
                    Eigen::Ref<Eigen::VectorXd> squared);

class Projector;

/// Projects the rows of `spectra` (n x B) and reconstructs them into caller-owned coefficients (n x k),
/// reconstruction (n x B) and L2 errors (n); returns the errors of the rows `mask` keeps (n bytes, nonzero = kept;
/// empty: all). UsageError on other sizes.
ProjectionError project_rows(const Projector& projector, const Eigen::Ref<const RowMatrixXd>& spectra,
                             std::span<const std::uint8_t> mask, Eigen::Ref<RowMatrixXd> coefficients,
                             Eigen::Ref<RowMatrixXd> reconstruction, Eigen::Ref<Eigen::VectorXd> error);

/// Projection onto one basis; construct once, then project and reconstruct from any number of threads at once.
class Projector {
 public:
  /// PCA: the first k components (1 <= k <= basis.k(); no k: all); NMF: all components (k, if given, must equal
  /// basis.k()). `name` names the basis in messages. InputError as basis_method(); UsageError naming k otherwise.
  Projector(const store::Basis& basis, std::optional<long long> k, const std::string& name = "");

  /// The basis's method.
  BasisMethod method() const { return method_; }
  /// Coefficients per spectrum.
  std::size_t k() const { return std::size_t(basis_.components.rows()); }
  /// Bands per spectrum, those of the basis.
  std::size_t bands() const { return basis_.bands(); }
  /// The basis as projected on: method, wavelengths, mean and the k components used (no statistics).
  const store::Basis& basis() const { return basis_; }
  /// InputError unless `grid` (the wavelengths of `what`, e.g. "image x") matches the basis's; `hint` is appended.
  void check_wavelengths(const WavelengthGrid& grid, const std::string& what, const std::string& hint = "") const;

  /// Coefficients (n x k) of the rows of `spectra` (n x B): PCA (x - mean) V_k^T, NMF the exact NNLS solution;
  /// UsageError on other sizes; safe to call concurrently.
  void project(const Eigen::Ref<const RowMatrixXd>& spectra, Eigen::Ref<RowMatrixXd> coefficients) const;
  /// Spectra (n x B) from coefficients (n x k): PCA mean + c V_k, NMF c S; UsageError on other sizes; safe to call
  /// concurrently.
  void reconstruct(const Eigen::Ref<const RowMatrixXd>& coefficients, Eigen::Ref<RowMatrixXd> spectra) const;

 private:
  BasisMethod method_;
  std::string label_;             // "basis <name>" or "the basis"
  store::Basis basis_;            // method, wavelengths, mean and the k components used
  std::optional<GramNnls> nnls_;  // NMF: the solver for S S^T
};

/// The projection of an image: its summary and the per-pixel L2 error over bands (0 for masked pixels).
struct ImageProjection {
  std::size_t k = 0;
  double rms = 0, max_error = 0;  ///< as ProjectionError::rms() and max_error, over the valid pixels
  std::vector<float> error;       ///< height x width
};

/// Projects every pixel of `cube` (eq 7.2 or NNLS) and reconstructs it (eq 7.3) into `reconstruction` (as many values
/// as the cube's; masked pixels 0, as the store keeps them), in row blocks of about 2^20 doubles: memory bounded by
/// the block. UsageError on other sizes.
ImageProjection project_image(const store::Cube& cube, const Projector& projector, std::span<float> reconstruction);

/// One spectrum reconstructed on a basis, its L2 error ||x - x'|| and that error over ||x|| (0 for a zero spectrum).
struct SpectrumReconstruction {
  std::size_t k = 0;  ///< components used (PCA: 0 is the mean alone)
  std::vector<double> values;
  double l2_error = 0, relative_error = 0;
};

/// Reconstructs `spectrum` (on `grid`, called `what` in messages) from `basis` (called `name`): PCA from its first k
/// components (k = 0: the mean alone; none: all), NMF from all of them (k ignored). InputError as Projector and
/// Projector::check_wavelengths; UsageError for a k the basis does not have.
SpectrumReconstruction reconstruct_spectrum(const store::Basis& basis, const std::string& name,
                                            std::optional<std::size_t> k, std::span<const float> spectrum,
                                            const WavelengthGrid& grid, const std::string& what);

}  // namespace specula::stats
