#include "specula/stats/learn_pca.h"

#include <fmt/format.h>
#include <omp.h>

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "specula/core/error.h"
#include "specula/stats/moments.h"
#include "specula/stats/pca.h"
#include "specula/store/learned_basis.h"

namespace specula::stats {

LearnedPca learn_pca(const std::vector<store::Store>& stores, const store::Selection& selection, std::size_t k,
                     const Collective& ranks) {
  const store::BlockReader reader(stores, selection);
  if (k > reader.bands()) throw UsageError(fmt::format("pca: k = {}: the data has {} bands", k, reader.bands()));
  if (reader.spectra() < 2)
    throw InputError(fmt::format("{}: the selection holds {} valid spectra; PCA needs at least two",
                                 stores.front().label(), reader.spectra()));
  const auto t0 = std::chrono::steady_clock::now();
  const Moments moments = stream_moments(reader, ranks);
  const auto t1 = std::chrono::steady_clock::now();
  LearnedPca out;
  out.basis = pca_basis(moments, reader.wavelengths(), k);
  out.stream_seconds = std::chrono::duration<double>(t1 - t0).count();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.basis.source = store::selection_source(reader, selection);
  out.basis.provenance.source_file = store::source_files(stores);
  out.basis.provenance.importer = "pca";
  return out;
}

nlohmann::ordered_json pca_report_json(const LearnedPca& learned, const std::string& store, const std::string& name,
                                       const std::string& output, std::size_t ranks) {
  const store::Basis& basis = learned.basis;
  auto numbers = [](const Eigen::VectorXd& v) {
    return nlohmann::ordered_json(std::vector<double>(v.data(), v.data() + v.size()));
  };
  nlohmann::ordered_json j;
  j["store"] = store;
  j["basis"] = name;
  j["output"] = output;
  j["n"] = basis.n;
  j["bands"] = basis.bands();
  const auto nm = basis.wavelengths.values();
  j["wavelengths"] = std::vector<double>(nm.begin(), nm.end());
  j["mean"] = numbers(basis.mean);
  j["eigenvalues"] = numbers(basis.eigenvalues);
  j["explained_variance_ratio"] = numbers(basis.explained_variance_ratio);
  j["components"] = basis.k();
  j["seconds"] = learned.seconds;
  j["stream_seconds"] = learned.stream_seconds;
  j["spectra_per_s"] = std::round(double(basis.n) / learned.stream_seconds);
  j["threads"] = omp_get_max_threads();
  j["ranks"] = ranks;
  return j;
}

}  // namespace specula::stats
