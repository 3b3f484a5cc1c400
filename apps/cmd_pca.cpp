// specula pca (reference §7.3): the covariance of every valid spectrum of the selected images (or a
// collection) in one exact streaming pass, its eigen-decomposition, and the basis saved in a store.
#include <fmt/format.h>
#include <omp.h>

#include <cmath>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/stats/learn_pca.h"
#include "specula/store/learned_basis.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct PcaOptions {
  std::vector<std::string> stores;
  std::vector<std::string> images;
  std::string collection;
  std::string name = "pca";
  std::string output;
  std::size_t k = 0;
  bool json = false;
  bool replace = false;
};

void run_pca(const PcaOptions& o) {
  const std::string out = basis_output(o.stores, o.output);
  const std::vector<store::Store> stores = open_stores(o.stores);
  const store::Store& s = stores.front();
  const stats::LearnedPca learned =
      stats::learn_pca(stores, {.image_globs = o.images, .collection = o.collection}, o.k, ranks());
  const store::Basis& basis = learned.basis;
  const std::string& source = basis.source;
  const double seconds = learned.seconds, stream_seconds = learned.stream_seconds;
  if (ranks().rank() != 0) return;  // rank 0 writes and reports

  store::save_basis(out, o.name, basis, o.replace, command_line());

  if (o.json) {
    print_json(stats::pca_report_json(learned, s.path().string(), o.name, out, std::size_t(ranks().size())));
    return;
  }
  fmt::print("PCA of {} spectra ({}) from {} in {:.3f} s ({:.1f} M spectra/s, {} threads)\n", basis.n,
             basis.wavelengths.describe(), source.size() > 80 ? source.substr(0, 77) + "..." : source, seconds,
             double(basis.n) / stream_seconds / 1e6, omp_get_max_threads());
  double cumulative = 0;
  fmt::print("component  eigenvalue      explained  cumulative\n");
  for (Eigen::Index i = 0; i < basis.eigenvalues.size() && i < 8; ++i) {
    cumulative += basis.explained_variance_ratio[i];
    fmt::print("{:>9}  {:<14.6e}  {:>8.4f}%  {:>9.4f}%\n", i + 1, basis.eigenvalues[i],
               100 * basis.explained_variance_ratio[i], 100 * cumulative);
  }
  fmt::print("saved basis '{}' ({} components) in {}\n", o.name, basis.k(), out);
}

}  // namespace

void setup_pca(CLI::App& app) {
  auto o = std::make_shared<PcaOptions>();
  auto* cmd = app.add_subcommand("pca", "Principal components of every valid spectrum, in one exact streaming pass");
  cmd->add_option("stores", o->stores, "Store file(s); several are analysed as one database")->required();
  cmd->add_option("--images", o->images, "Image name globs (default: every image)");
  cmd->add_option("--collection", o->collection, "Use this collection instead of images");
  cmd->add_option("--name", o->name, "Name of the basis to save")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "Store to save the basis in (default: the first input store)");
  cmd->add_option("-k", o->k, "Components to keep (default: all)");
  cmd->add_flag("--json", o->json, "Print one JSON object (n, bands, wavelengths, mean, eigenvalues, ...)");
  cmd->add_flag("--replace", o->replace, "Replace a basis of the same name");
  cmd->callback([o] { run_pca(*o); });
}

}  // namespace specula::app
