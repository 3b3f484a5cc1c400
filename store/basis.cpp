// Learned bases (PCA, NMF): components, mean and the statistics that came with them.
#include <algorithm>
#include <string>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"

namespace specula::store {

Basis Store::read_basis(const std::string& name) const {
  const std::string path = "/bases/" + name;
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(StoreAccess::root(*this), path))
    throw InputError(label() + ": no basis '" + name + "' (bases: " + join(bases()) + ")");
  const std::string ctx = label() + ": " + path;
  h5::Id g = open_group(StoreAccess::root(*this), path, ctx);
  Basis b;
  b.method = h5::read_string_attr(g, "method", ctx);
  b.n = std::uint64_t(std::max(0LL, h5::read_int_attr(g, "n", ctx)));
  b.source = h5::has_attr(g, "source") ? h5::read_string_attr(g, "source", ctx) : "";
  b.provenance = read_provenance(g, ctx);
  read_components(g, ctx, b);
  auto vec = [&](const char* nm) {
    return h5::exists(g, nm) ? to_vector(h5::read_vector(g, nm, ctx)) : Eigen::VectorXd();
  };
  b.mean = vec("mean");
  b.eigenvalues = vec("eigenvalues");
  b.explained_variance_ratio = vec("explained_variance_ratio");
  b.weights = vec("weights");
  if (h5::exists(g, "covariance")) b.covariance = h5::read_matrix(g, "covariance", ctx);
  if (h5::exists(g, "second_moment")) b.second_moment = h5::read_matrix(g, "second_moment", ctx);
  if (b.mean.size() && b.mean.size() != b.components.cols())
    throw InputError(ctx + ": mean has " + std::to_string(b.mean.size()) + " entries for " +
                     std::to_string(b.components.cols()) + " bands");
  return b;
}

void StoreWriter::add_basis(const std::string& name, const Basis& basis) {
  const std::string ctx = label() + ": /bases/" + name;
  const auto b = Eigen::Index(basis.bands());
  if (b == 0 || basis.components.cols() != b || basis.components.rows() == 0)
    throw UsageError(ctx + ": a basis needs k x B components on its wavelength grid");
  auto check_len = [&](const Eigen::VectorXd& v, const char* what) {
    if (v.size() != 0 && v.size() != b && std::string(what) != "weights")
      throw UsageError(ctx + ": " + what + " has " + std::to_string(v.size()) + " entries for " + std::to_string(b) +
                       " bands");
  };
  check_len(basis.mean, "mean");
  check_len(basis.eigenvalues, "eigenvalues");
  check_len(basis.explained_variance_ratio, "explained_variance_ratio");
  if (!basis.components.allFinite()) throw InputError(ctx + ": basis has non-finite components");
  h5::Id g = make_group(begin("bases", name, "basis"), "/bases/" + name, ctx);
  h5::write_attr(g, "kind", std::string_view("basis"), ctx);
  h5::write_attr(g, "method", std::string_view(basis.method), ctx);
  h5::write_attr(g, "n", static_cast<long long>(basis.n), ctx);
  h5::write_attr(g, "source", std::string_view(basis.source), ctx);
  write_provenance(g, basis.provenance, options_.command_line, ctx);
  write_grid(g, basis.wavelengths, ctx);
  h5::write_matrix(g, "components", basis.components, ctx);
  auto vec = [&](const char* nm, const Eigen::VectorXd& v) {
    if (v.size()) h5::write_vector(g, nm, std::span<const double>(v.data(), std::size_t(v.size())), ctx);
  };
  vec("mean", basis.mean);
  vec("eigenvalues", basis.eigenvalues);
  vec("explained_variance_ratio", basis.explained_variance_ratio);
  vec("weights", basis.weights);
  if (basis.covariance.size()) h5::write_matrix(g, "covariance", basis.covariance, ctx);
  if (basis.second_moment.size()) h5::write_matrix(g, "second_moment", basis.second_moment, ctx);
}

}  // namespace specula::store
