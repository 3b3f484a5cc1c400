#pragma once
// Learned spectral bases in a store (/bases/<name>): PCA (mean, eigenvalues, components) and NMF
// (components, weights). Layout: docs/store-format.md.
#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "specula/core/wavelengths.h"
#include "specula/store/cube.h"

namespace specula::store {

/// A learned basis. Components are rows (k x B). For PCA: mean (B), eigenvalues of the covariance
/// (all B, descending), explained_variance_ratio (B), covariance and second_moment (B x B, uncentred E[x x^T]).
struct Basis {
  std::string method;  ///< "pca" or "nmf"
  WavelengthGrid wavelengths;
  std::uint64_t n = 0;  ///< spectra it was learned from
  Eigen::VectorXd mean;
  Eigen::MatrixXd components;
  Eigen::VectorXd eigenvalues;
  Eigen::VectorXd explained_variance_ratio;
  Eigen::MatrixXd covariance;
  Eigen::MatrixXd second_moment;
  Eigen::VectorXd weights;  ///< NMF: per-component scale (may be empty)
  std::string source;       ///< what it was learned from, e.g. "images synth*" or "collection munsell"
  Provenance provenance;

  std::size_t bands() const { return wavelengths.size(); }
  std::size_t k() const { return std::size_t(components.rows()); }
};

}  // namespace specula::store
