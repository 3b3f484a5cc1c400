#pragma once
// A learned basis as text tables: what `specula plot-basis` writes as CSV and plots.
#include <Eigen/Core>
#include <string>

#include "specula/store/basis.h"

namespace specula::stats {

/// The explained-variance ratio of each eigenvalue of a PCA basis: the stored ratio when it has one per eigenvalue,
/// else the eigenvalues over their sum (over 1 when the sum is not positive).
Eigen::VectorXd explained_ratio(const store::Basis& basis);
/// One line "index,eigenvalue,explained_ratio,cumulative_ratio" per eigenvalue, after that header.
std::string eigenvalues_csv(const store::Basis& basis);
/// One line "index eigenvalue" per eigenvalue (gnuplot data), no header.
std::string eigenvalues_rows(const store::Basis& basis);
/// One line per band: the wavelength and the first `n` components (n <= k), separated by `separator`, no header.
std::string components_rows(const store::Basis& basis, std::size_t n, char separator);
/// The header "wavelength_nm,c1,...,cn" and components_rows(basis, n, ',').
std::string components_csv(const store::Basis& basis, std::size_t n);

}  // namespace specula::stats
