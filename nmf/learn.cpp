#include "specula/nmf/learn.h"

#include <fmt/format.h>

#include "specula/store/learned_basis.h"

namespace specula::nmf {

std::string init_name(Init init) { return init == Init::nndsvd ? "nndsvd" : "random"; }

std::string default_basis_name(std::size_t k) { return fmt::format("nmf{}", k); }

std::filesystem::path default_checkpoint(const std::filesystem::path& output, const std::string& name) {
  return std::filesystem::path(output.string() + ".nmf-" + name + ".checkpoint");
}

LearnedBasis learn_basis(const std::vector<store::Store>& stores, const store::Selection& selection,
                         const NmfOptions& options, const Collective& ranks) {
  const store::BlockReader reader(stores, selection);
  LearnedBasis out;
  out.result = factorize(reader, options, ranks);
  out.bands = reader.bands();
  const NmfResult& r = out.result;
  store::Basis& basis = out.basis;
  basis.method = "nmf";
  basis.wavelengths = reader.wavelengths();
  basis.n = r.n;
  basis.components = r.best_result().basis;
  basis.weights = r.weights;
  basis.second_moment = r.second_moment;
  basis.source = store::selection_source(reader, selection);
  basis.provenance.source_file = store::source_files(stores);
  basis.provenance.importer =
      fmt::format("nmf k={} init={} seed={} restarts={} rel_error={:.9g} svd_bound={:.9g}", options.k,
                  init_name(options.init), options.seed, options.restarts, r.rel_error, r.svd_bound);
  return out;
}

}  // namespace specula::nmf
