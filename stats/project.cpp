#include "specula/stats/project.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "specula/core/error.h"
#include "specula/stats/pca.h"

namespace specula::stats {
namespace {

std::string label(const std::string& name) { return name.empty() ? "the basis" : "basis " + name; }

std::string sizes(Eigen::Index rows, Eigen::Index cols) { return std::to_string(rows) + " x " + std::to_string(cols); }

}  // namespace

BasisMethod basis_method(const store::Basis& basis, const std::string& name) {
  if (basis.method == "nmf") return BasisMethod::nmf;
  if (basis.method != "pca")
    throw InputError(label(name) + " has method '" + basis.method +
                     "'; projection needs a pca basis (with its mean) or an nmf basis");
  if (std::size_t(basis.mean.size()) != basis.bands() || basis.components.cols() != basis.mean.size())
    throw InputError(label(name) + " is a pca basis without a mean of its " + std::to_string(basis.bands()) +
                     " bands; PCA projects about the mean (eq 7.2), so re-learn the basis by PCA");
  return BasisMethod::pca;
}

void ProjectionError::add(double squared) {
  ++count;
  sum_sq += squared;
  max_error = std::max(max_error, std::sqrt(squared));
}

void ProjectionError::merge(const ProjectionError& other) {
  count += other.count;
  sum_sq += other.sum_sq;
  max_error = std::max(max_error, other.max_error);
}

double ProjectionError::rms(std::size_t bands) const {
  if (count == 0 || bands == 0) return std::numeric_limits<double>::quiet_NaN();
  return std::sqrt(sum_sq / (double(count) * double(bands)));
}

void squared_errors(const Eigen::Ref<const RowMatrixXd>& spectra, const Eigen::Ref<const RowMatrixXd>& reconstruction,
                    Eigen::Ref<Eigen::VectorXd> squared) {
  if (reconstruction.rows() != spectra.rows() || reconstruction.cols() != spectra.cols() ||
      squared.size() != spectra.rows())
    throw UsageError("squared_errors: spectra " + sizes(spectra.rows(), spectra.cols()) + ", reconstruction " +
                     sizes(reconstruction.rows(), reconstruction.cols()) + ", squared " +
                     std::to_string(squared.size()) + " do not match");
  for (Eigen::Index i = 0; i < spectra.rows(); ++i) squared[i] = (spectra.row(i) - reconstruction.row(i)).squaredNorm();
}

ProjectionError project_rows(const Projector& projector, const Eigen::Ref<const RowMatrixXd>& spectra,
                             std::span<const std::uint8_t> mask, Eigen::Ref<RowMatrixXd> coefficients,
                             Eigen::Ref<RowMatrixXd> reconstruction, Eigen::Ref<Eigen::VectorXd> error) {
  if (!mask.empty() && mask.size() != std::size_t(spectra.rows()))
    throw UsageError("project_rows: mask has " + std::to_string(mask.size()) + " entries for " +
                     std::to_string(spectra.rows()) + " spectra; give one per spectrum or none");
  projector.project(spectra, coefficients);
  projector.reconstruct(coefficients, reconstruction);
  squared_errors(spectra, reconstruction, error);
  ProjectionError summary;
  for (Eigen::Index i = 0; i < spectra.rows(); ++i) {
    if (mask.empty() || mask[std::size_t(i)]) summary.add(error[i]);
    error[i] = std::sqrt(error[i]);
  }
  return summary;
}

Projector::Projector(const store::Basis& basis, std::optional<long long> k, const std::string& name)
    : method_(basis_method(basis, name)), label_(label(name)) {
  const auto all = static_cast<long long>(basis.k());
  if (all < 1 || basis.components.cols() != Eigen::Index(basis.bands()))
    throw InputError(label_ + " has components " + sizes(basis.components.rows(), basis.components.cols()) + " for " +
                     std::to_string(basis.bands()) + " wavelengths");
  if (method_ == BasisMethod::pca && k && (*k < 1 || *k > all))
    throw UsageError("k = " + std::to_string(*k) + ": " + label_ + " has " + std::to_string(all) +
                     " components; give k between 1 and " + std::to_string(all));
  if (method_ == BasisMethod::nmf && k && *k != all)
    throw UsageError("k = " + std::to_string(*k) + ": NMF " + (name.empty() ? "basis" : label_) + " has " +
                     std::to_string(all) +
                     " components and projects onto all of them (NMF bases are not nested: a "
                     "basis projects onto all of its " +
                     std::to_string(all) + " components, and its first " + std::to_string(*k) + " are no " +
                     std::to_string(*k) + "-component basis)");
  const Eigen::Index used = method_ == BasisMethod::pca && k ? Eigen::Index(*k) : Eigen::Index(all);
  basis_.method = basis.method;
  basis_.wavelengths = basis.wavelengths;
  basis_.mean = basis.mean;
  basis_.components = basis.components.topRows(used);
  if (method_ == BasisMethod::nmf) nnls_.emplace(basis_.components * basis_.components.transpose());
}

void Projector::check_wavelengths(const WavelengthGrid& grid, const std::string& what, const std::string& hint) const {
  if (grid.approx_equal(basis_.wavelengths)) return;
  throw InputError(what + " has " + grid.describe() + ", " + label_ + " has " + basis_.wavelengths.describe() +
                   (hint.empty() ? "" : "; " + hint));
}

void Projector::project(const Eigen::Ref<const RowMatrixXd>& spectra, Eigen::Ref<RowMatrixXd> coefficients) const {
  const auto k = Eigen::Index(this->k()), b = Eigen::Index(bands());
  if (spectra.cols() != b || coefficients.rows() != spectra.rows() || coefficients.cols() != k)
    throw UsageError("project: spectra are " + sizes(spectra.rows(), spectra.cols()) + " and coefficients " +
                     sizes(coefficients.rows(), coefficients.cols()) + "; " + label_ + " needs " + std::to_string(b) +
                     " bands and gives " + std::to_string(k) + " coefficients per spectrum");
  if (method_ == BasisMethod::pca) {
    pca_project(basis_, std::size_t(k), spectra, coefficients);
    return;
  }
  // Exact NNLS per spectrum; neighbouring spectra usually share their passive set, so each hints the next.
  const RowMatrixXd h = spectra * basis_.components.transpose();
  std::uint64_t hint = 0;
  Eigen::VectorXd c(k);
  for (Eigen::Index r = 0; r < spectra.rows(); ++r) {
    nnls_->solve(h.data() + r * k, c.data(), hint);
    coefficients.row(r) = c.transpose();
  }
}

void Projector::reconstruct(const Eigen::Ref<const RowMatrixXd>& coefficients, Eigen::Ref<RowMatrixXd> spectra) const {
  const auto k = Eigen::Index(this->k()), b = Eigen::Index(bands());
  if (coefficients.cols() != k || spectra.rows() != coefficients.rows() || spectra.cols() != b)
    throw UsageError("reconstruct: coefficients are " + sizes(coefficients.rows(), coefficients.cols()) +
                     " and spectra " + sizes(spectra.rows(), spectra.cols()) + "; " + label_ + " takes " +
                     std::to_string(k) + " coefficients and gives " + std::to_string(b) + " bands per spectrum");
  if (method_ == BasisMethod::pca) {
    pca_reconstruct(basis_, coefficients, spectra);
    return;
  }
  spectra.noalias() = coefficients * basis_.components;
}

ImageProjection project_image(const store::Cube& cube, const Projector& projector, std::span<float> reconstruction) {
  const std::size_t w = cube.width, b = cube.bands, k = projector.k();
  if (reconstruction.size() != cube.data.size())
    throw UsageError("project_image: " + std::to_string(reconstruction.size()) +
                     " values for the reconstruction of a " + std::to_string(cube.data.size()) + "-value image");
  const std::size_t rows_per_block = std::max<std::size_t>(1, (std::size_t(1) << 20) / (w * b));
  ImageProjection r;
  r.k = k;
  r.error.assign(cube.height * w, 0.0f);
  std::fill(reconstruction.begin(), reconstruction.end(), 0.0f);
  ProjectionError summary;
  RowMatrixXd x, coef, xr;
  Eigen::VectorXd err;
  for (std::size_t y0 = 0; y0 < cube.height; y0 += rows_per_block) {
    const Eigen::Index m = Eigen::Index(std::min(rows_per_block, cube.height - y0) * w);
    const std::size_t first = y0 * w;
    x = Eigen::Map<const RowMatrixXf>(cube.data.data() + first * b, m, Eigen::Index(b)).cast<double>();
    coef.resize(m, Eigen::Index(k));
    xr.resize(m, Eigen::Index(b));
    err.resize(m);
    const std::span<const std::uint8_t> mask =
        cube.mask.empty() ? std::span<const std::uint8_t>() : std::span(cube.mask).subspan(first, std::size_t(m));
    summary.merge(project_rows(projector, x, mask, coef, xr, err));
    Eigen::Map<RowMatrixXf>(reconstruction.data() + first * b, m, Eigen::Index(b)) = xr.cast<float>();
    for (Eigen::Index i = 0; i < m; ++i) {
      const std::size_t p = first + std::size_t(i);
      if (mask.empty() || mask[std::size_t(i)]) {
        r.error[p] = float(err[i]);
      } else {
        std::fill_n(reconstruction.begin() + std::ptrdiff_t(p * b), b, 0.0f);
      }
    }
  }
  r.rms = summary.rms(b);
  r.max_error = summary.max_error;
  return r;
}

SpectrumReconstruction reconstruct_spectrum(const store::Basis& basis, const std::string& name,
                                            std::optional<std::size_t> k, std::span<const float> spectrum,
                                            const WavelengthGrid& grid, const std::string& what) {
  const bool pca = basis_method(basis, name) == BasisMethod::pca;
  if (!pca) k.reset();
  const Projector projector(basis, k ? std::optional<long long>(std::max<std::size_t>(*k, 1)) : std::nullopt, name);
  projector.check_wavelengths(grid, what);
  if (spectrum.size() != projector.bands())
    throw UsageError("reconstruct_spectrum: " + std::to_string(spectrum.size()) + " values for a basis of " +
                     std::to_string(projector.bands()) + " bands");
  RowMatrixXd x(1, Eigen::Index(spectrum.size())), r(1, Eigen::Index(spectrum.size()));
  for (std::size_t i = 0; i < spectrum.size(); ++i) x(0, Eigen::Index(i)) = spectrum[i];
  RowMatrixXd coef(1, Eigen::Index(projector.k()));
  projector.project(x, coef);
  if (k && *k == 0) coef.setZero();
  projector.reconstruct(coef, r);
  SpectrumReconstruction out;
  out.k = k ? *k : projector.k();
  out.values.assign(r.data(), r.data() + r.size());
  const double norm = x.norm();
  out.l2_error = (x - r).norm();
  out.relative_error = norm > 0 ? out.l2_error / norm : 0.0;
  return out;
}

}  // namespace specula::stats
