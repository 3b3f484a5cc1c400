// specula pca (reference §7.3): the covariance of every valid spectrum of the selected images (or a
// collection) in one exact streaming pass, its eigen-decomposition, and the basis saved in a store.
#include <fmt/format.h>
#include <omp.h>

#include <chrono>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/ranks.h"
#include "specula/core/error.h"
#include "specula/stats/moments.h"
#include "specula/stats/pca.h"
#include "specula/store/block_reader.h"
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
  const store::BlockReader reader(stores, {.image_globs = o.images, .collection = o.collection});
  if (o.k > reader.bands())
    throw UsageError(fmt::format("-k {}: the data has {} bands", o.k, reader.bands()));
  if (reader.spectra() < 2)
    throw InputError(fmt::format("{}: the selection holds {} valid spectra; PCA needs at least two", s.label(),
                                 reader.spectra()));
  const auto t0 = std::chrono::steady_clock::now();
  const stats::Moments moments = stats::stream_moments(reader, ranks());
  const auto t1 = std::chrono::steady_clock::now();
  store::Basis basis = stats::pca_basis(moments, reader.wavelengths(), o.k);
  const double stream_seconds = std::chrono::duration<double>(t1 - t0).count();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::string source;
  if (!o.collection.empty()) {
    source = "collection " + o.collection;
  } else {
    source = "images";
    for (const auto& n : reader.source_names()) source += " " + n;
  }
  basis.source = source;
  for (const auto& st : stores)
    basis.provenance.source_file += (basis.provenance.source_file.empty() ? "" : " ") + st.path().string();
  basis.provenance.importer = "pca";
  if (ranks().rank() != 0) return;  // rank 0 writes and reports

  store::StoreWriter writer(out, {.compression = {}, .replace = o.replace, .command_line = command_line()});
  writer.add_basis(o.name, basis);
  writer.commit();

  if (o.json) {
    const Eigen::VectorXd& ev = basis.eigenvalues;
    fmt::print(R"({{"store":{},"basis":{},"output":{},"n":{},"bands":{},"wavelengths":{},"mean":{},"eigenvalues":{},)"
               R"("explained_variance_ratio":{},"components":{},"seconds":{:.6f},"stream_seconds":{:.6f},)"
               R"("spectra_per_s":{:.0f},"threads":{},"ranks":{}}})"
               "\n",
               json_string(s.path().string()), json_string(o.name), json_string(out), basis.n, basis.bands(),
               json_array(basis.wavelengths.values()), json_array({basis.mean.data(), std::size_t(basis.mean.size())}),
               json_array({ev.data(), std::size_t(ev.size())}),
               json_array({basis.explained_variance_ratio.data(), std::size_t(basis.explained_variance_ratio.size())}),
               basis.k(), seconds, stream_seconds, double(basis.n) / stream_seconds, omp_get_max_threads(),
               ranks().size());
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
