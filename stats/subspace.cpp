#include "specula/stats/subspace.h"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "specula/core/error.h"

namespace specula::stats {
namespace {

void check_pair(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const char* what) {
  if (a.rows() == 0 || b.rows() == 0) throw UsageError(std::string(what) + ": both bases need at least one component");
  if (a.cols() != b.cols())
    throw UsageError(std::string(what) + ": the bases have " + std::to_string(a.cols()) + " and " +
                     std::to_string(b.cols()) + " bands; they must share a wavelength grid");
  if (!a.allFinite() || !b.allFinite()) throw InputError(std::string(what) + ": a component holds NaN or Inf");
}

// Orthonormal basis (B x rank) of the row space of m, by column-pivoted Householder QR of m^T.
Eigen::MatrixXd orthonormal_rows(const Eigen::MatrixXd& m) {
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(m.transpose());
  const Eigen::Index rank = qr.rank();
  if (rank == 0) throw InputError("principal angles: a basis has only zero components");
  Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(m.cols(), rank);
  return q;
}

}  // namespace

Eigen::VectorXd principal_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  check_pair(a, b, "principal angles");
  Eigen::MatrixXd qa = orthonormal_rows(a), qb = orthonormal_rows(b);
  if (qa.cols() < qb.cols()) std::swap(qa, qb);
  const Eigen::Index p = qb.cols();
  const Eigen::MatrixXd m = qa.transpose() * qb;
  // Cosines lose the small angles (acos near 1); sines of the residual (I - Qa Qa^T) Qb keep them
  // (Knyazev & Argentati 2002). Both sets pair by sorted order.
  Eigen::VectorXd cosines = Eigen::JacobiSVD<Eigen::MatrixXd>(m).singularValues();
  Eigen::VectorXd sines = Eigen::JacobiSVD<Eigen::MatrixXd>(qb - qa * m).singularValues();
  std::sort(cosines.data(), cosines.data() + p, std::greater<>());
  std::sort(sines.data(), sines.data() + sines.size());
  Eigen::VectorXd angles(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    const double c = std::clamp(cosines[i], 0.0, 1.0);
    const double s = i < sines.size() ? std::clamp(sines[i], 0.0, 1.0) : 0.0;
    angles[i] = c * c < 0.5 ? std::acos(c) : std::asin(s);
  }
  std::sort(angles.data(), angles.data() + p);
  return angles;
}

std::vector<std::vector<double>> principal_angles_deg(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                                      std::size_t k_max) {
  std::vector<std::vector<double>> degrees;
  for (std::size_t k = 1; k <= k_max; ++k) {
    const Eigen::VectorXd angles = principal_angles(a.topRows(Eigen::Index(k)), b.topRows(Eigen::Index(k)));
    std::vector<double> row(std::size_t(angles.size()));
    for (Eigen::Index i = 0; i < angles.size(); ++i) row[std::size_t(i)] = angles[i] * 180.0 / std::numbers::pi;
    degrees.push_back(std::move(row));
  }
  return degrees;
}

AlignedComponents align_components(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  check_pair(a, b, "aligning components");
  const Eigen::Index k = std::min(a.rows(), b.rows());
  auto unit = [](const Eigen::MatrixXd& m) {
    Eigen::MatrixXd u = m;
    for (Eigen::Index i = 0; i < u.rows(); ++i)
      if (const double n = u.row(i).norm(); n > 0) u.row(i) /= n;
    return u;
  };
  const Eigen::MatrixXd cosines = unit(a.topRows(k)) * unit(b).transpose();
  AlignedComponents out;
  out.components.resize(k, b.cols());
  out.order.assign(std::size_t(k), 0);
  out.sign.assign(std::size_t(k), 1);
  std::vector<bool> a_done(std::size_t(k), false), b_done(std::size_t(b.rows()), false);
  for (Eigen::Index step = 0; step < k; ++step) {
    Eigen::Index best_i = -1, best_j = -1;
    double best = -1;
    for (Eigen::Index i = 0; i < k; ++i) {
      if (a_done[std::size_t(i)]) continue;
      for (Eigen::Index j = 0; j < b.rows(); ++j)
        if (!b_done[std::size_t(j)] && std::abs(cosines(i, j)) > best) {
          best = std::abs(cosines(i, j));
          best_i = i;
          best_j = j;
        }
    }
    a_done[std::size_t(best_i)] = b_done[std::size_t(best_j)] = true;
    const int sign = cosines(best_i, best_j) < 0 ? -1 : 1;
    out.order[std::size_t(best_i)] = std::size_t(best_j);
    out.sign[std::size_t(best_i)] = sign;
    out.components.row(best_i) = double(sign) * b.row(best_j);
  }
  return out;
}

}  // namespace specula::stats
