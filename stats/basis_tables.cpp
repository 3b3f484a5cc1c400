#include "specula/stats/basis_tables.h"

#include <fmt/format.h>

namespace specula::stats {

Eigen::VectorXd explained_ratio(const store::Basis& b) {
  const Eigen::VectorXd& ev = b.eigenvalues;
  if (b.explained_variance_ratio.size() == ev.size()) return b.explained_variance_ratio;
  return ev / (ev.sum() > 0 ? ev.sum() : 1.0);
}

std::string eigenvalues_csv(const store::Basis& b) {
  const Eigen::VectorXd& ev = b.eigenvalues;
  const Eigen::VectorXd ratio = explained_ratio(b);
  std::string csv = "index,eigenvalue,explained_ratio,cumulative_ratio\n";
  double cumulative = 0;
  for (Eigen::Index i = 0; i < ev.size(); ++i) {
    cumulative += ratio[i];
    csv += fmt::format("{},{},{},{}\n", i + 1, ev[i], ratio[i], cumulative);
  }
  return csv;
}

std::string eigenvalues_rows(const store::Basis& b) {
  std::string rows;
  for (Eigen::Index i = 0; i < b.eigenvalues.size(); ++i) rows += fmt::format("{} {}\n", i + 1, b.eigenvalues[i]);
  return rows;
}

std::string components_rows(const store::Basis& b, std::size_t n, char separator) {
  std::string rows;
  for (std::size_t w = 0; w < b.bands(); ++w) {
    rows += fmt::format("{}", b.wavelengths[w]);
    for (std::size_t c = 0; c < n; ++c)
      rows += fmt::format("{}{}", separator, b.components(Eigen::Index(c), Eigen::Index(w)));
    rows += '\n';
  }
  return rows;
}

std::string components_csv(const store::Basis& b, std::size_t n) {
  std::string csv = "wavelength_nm";
  for (std::size_t c = 0; c < n; ++c) csv += fmt::format(",c{}", c + 1);
  return csv + "\n" + components_rows(b, n, ',');
}

}  // namespace specula::stats
