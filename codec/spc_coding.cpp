#include "specula/codec/spc_coding.h"

#include <algorithm>

#include "specula/codec/report_json.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::codec {
namespace {

// The bases of k spectra a source offers for an input, and the largest k.
struct BasisFamily {
  SpcBasisOfK of_k;
  std::size_t max_k = 0;
};

// A learned source's family, extended from `grid` (the input, or the grid samples resample to).
BasisFamily learned_family(const SpcBasisSource& source, const store::Grid& grid) {
  const std::size_t bands = grid.bands();
  const std::size_t max_k =
      std::max<std::size_t>(1, std::min(coding_basis_max_k(*source.learned), bands - std::min(bands, source.extra)));
  return {[&source, &grid](std::size_t k) {
            return augment_basis(coding_basis(*source.learned, k, source.reference), grid, source.extra);
          },
          max_k};
}

void check_own(const SpcBasisSource& source) {
  if (!source.learned && source.extra)
    throw UsageError("extra " + std::to_string(source.extra) +
                     " extends a learned basis; with the input's own spectra raise k instead");
}

BasisFamily grid_family(const SpcBasisSource& source, const store::Grid& grid) {
  check_own(source);
  if (source.learned) return learned_family(source, grid);
  return {[&grid](std::size_t k) { return self_basis(grid, k); }, grid.bands()};
}

// What every transform or samples coding does first: the basis at a given k, and without a target the coding at
// options.step. True when that finished it.
template <class Input, class Options>
bool code_at_step(SpcCoding& c, const Input& input, const BasisFamily& family, std::size_t k, const Options& options,
                  const SpcTargetSearch* target, const std::string& label) {
  c.max_k = family.max_k;
  if (k) c.basis = family.of_k(k);
  if (target) {
    c.target.emplace();
    return false;
  }
  c.bytes = encode_spc(input, c.basis, options, &c.report, label);
  return true;
}

void check_k(std::size_t k, const SpcTargetSearch* target, const char* what) {
  if (k == 0 && !target) throw UsageError(std::string(what) + ": k 0 (k chosen) needs a target");
}

}  // namespace

SpcBasisSource read_basis_source(const std::string& spec, std::size_t extra, const std::string& what) {
  if (spec == "self") return {.extra = extra};
  const auto object = store::parse_object_spec(spec);
  if (!object || object->name.empty())
    throw UsageError(what + " takes STORE.h5:BASIS (a PCA or NMF basis learned by specula) or 'self', not '" + spec +
                     "'");
  const store::Store s = store::Store::open(object->file);
  return {.learned = std::make_shared<const store::Basis>(s.read_basis(object->name)),
          .reference = s.label() + ":" + object->name,
          .extra = extra};
}

SpcCoding code_grid(const store::Grid& grid, const SpcBasisSource& source, std::size_t k,
                    const SpcBoundedOptions& options, const std::string& label) {
  if (k == 0) throw UsageError("code_grid: the bounded method needs k (1 or more basis spectra)");
  const BasisFamily family = grid_family(source, grid);
  SpcCoding c{.basis = family.of_k(k), .max_k = family.max_k};
  c.bytes = encode_spc(grid, c.basis, options, &c.report, label);
  return c;
}

SpcCoding code_grid(const store::Grid& grid, const SpcBasisSource& source, std::size_t k,
                    const SpcTransformOptions& options, const SpcTargetSearch* target, const std::string& label) {
  check_k(k, target, "code_grid");
  const BasisFamily family = grid_family(source, grid);
  SpcCoding c;
  if (code_at_step(c, grid, family, k, options, target, label)) return c;
  if (k) {
    c.bytes = encode_spc_to_target(grid, c.basis, options, target->target, target->suite, *c.target, &c.report, label);
    return c;
  }
  c.k_search.emplace();
  c.bytes = encode_spc_choosing_k(grid, family.of_k, family.max_k, options, target->target, target->suite, *c.target,
                                  *c.k_search, &c.basis, &c.report, label);
  return c;
}

SpcCoding code_samples(const SpcSampleSet& samples, const SpcBasisSource& source, std::size_t k,
                       const SpcSamplesOptions& options, const SpcTargetSearch* target, const std::string& label) {
  check_own(source);
  check_k(k, target, "code_samples");
  // The grid the samples resample to exactly: what a target is judged against and what extends a learned basis.
  std::optional<store::Grid> reference;
  if (target || source.learned) reference = resample_samples(samples, options.rule);
  const BasisFamily family =
      source.learned
          ? learned_family(source, *reference)
          : BasisFamily{[&samples](std::size_t kk) { return self_basis(samples, kk); }, samples.wavelengths.size()};
  SpcCoding c;
  if (code_at_step(c, samples, family, k, options, target, label)) return c;
  // A given k is a search over that one basis.
  const SpcBasisOfK of_k = k ? SpcBasisOfK([&c](std::size_t) { return c.basis; }) : family.of_k;
  SpcKReport k_report;
  c.bytes = encode_spc_samples_choosing_k(samples, *reference, of_k, k ? 1 : family.max_k, options, target->target,
                                          target->suite, *c.target, k_report, &c.basis, &c.report, label);
  if (!k) c.k_search = std::move(k_report);
  return c;
}

nlohmann::ordered_json spc_coding_json(const SpcCoding& coding, const SpcBoundedOptions* bounded,
                                       const SpcTarget* target, double seconds, const std::string& label) {
  nlohmann::ordered_json j =
      spc_encode_json(coding.report, coding.basis, bounded, target, coding.target ? &*coding.target : nullptr,
                      spc_format_version(coding.bytes, label), seconds);
  if (coding.k_search) j["k_search"] = spc_k_search_json(*coding.k_search);
  return j;
}

}  // namespace specula::codec
