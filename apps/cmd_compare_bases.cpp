// specula compare-bases (reference §7.3.1): how close two learned bases are, as the principal angles
// between the spaces their first k components span, and a side-by-side plot of those components.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/gnuplot.h"
#include "specula/core/error.h"
#include "specula/stats/subspace.h"
#include "specula/store/store.h"

namespace specula::app {

namespace {

struct CompareBasesOptions {
  std::string store;
  std::string basis_a;
  std::string basis_b;
  std::string store_b;
  std::size_t k = 0;
  std::string plot;
  bool json = false;
};

void write_plot(const std::filesystem::path& gnuplot, const std::filesystem::path& target, const store::Basis& a,
                const store::Basis& b, const std::string& label_a, const std::string& label_b, std::size_t k) {
  const Eigen::MatrixXd first_a = a.components.topRows(Eigen::Index(k));
  const stats::AlignedComponents aligned = stats::align_components(first_a, b.components.topRows(Eigen::Index(k)));
  const double top = std::max(first_a.cwiseAbs().maxCoeff(), aligned.components.cwiseAbs().maxCoeff()) * 1.08;
  std::string script = "$D << EOD\n";
  for (std::size_t w = 0; w < a.bands(); ++w) {
    script += fmt::format("{}", a.wavelengths[w]);
    for (std::size_t c = 0; c < k; ++c) script += fmt::format(" {}", first_a(Eigen::Index(c), Eigen::Index(w)));
    for (std::size_t c = 0; c < k; ++c)
      script += fmt::format(" {}", aligned.components(Eigen::Index(c), Eigen::Index(w)));
    script += "\n";
  }
  script += "EOD\n";
  script += "set multiplot layout 1,2 title " +
            gnuplot_quote(fmt::format("First {} components: {} (left) and {} (right, matched and sign-aligned)", k,
                                      label_a, label_b)) +
            " noenhanced\n";
  script += "set grid\nset xzeroaxis lt -1 lw 0.5\nset key top right\nset xlabel 'wavelength (nm)'\n";
  script +=
      fmt::format("set xrange [{}:{}]\nset yrange [{}:{}]\n", a.wavelengths.front(), a.wavelengths.back(), -top, top);
  script += "set ylabel 'component weight'\nset title " + gnuplot_quote(label_a) + " noenhanced\nplot ";
  for (std::size_t c = 0; c < k; ++c)
    script += fmt::format("{}$D using 1:{} with lines lw 2 lc {} title 'a{}'", c ? ", " : "", c + 2, c + 1, c + 1);
  script += "\nunset ylabel\nset title " + gnuplot_quote(label_b) + " noenhanced\nplot ";
  for (std::size_t c = 0; c < k; ++c)
    script += fmt::format("{}$D using 1:{} with lines lw 2 lc {} title '{}b{}'", c ? ", " : "", k + c + 2, c + 1,
                          aligned.sign[c] < 0 ? "-" : "", aligned.order[c] + 1);
  script += "\nunset multiplot\n";
  plot_png(gnuplot, target, gnuplot_png_terminal(1400, 600), script);
}

void run_compare_bases(const CompareBasesOptions& o) {
  const store::Store sa = store::Store::open(o.store);
  const store::Store sb = o.store_b.empty() ? sa : store::Store::open(o.store_b);
  const store::Basis a = sa.read_basis(o.basis_a);
  const store::Basis b = sb.read_basis(o.basis_b);
  const std::string label_a = fmt::format("{} ({})", o.basis_a, sa.label());
  const std::string label_b = fmt::format("{} ({})", o.basis_b, sb.label());
  if (!a.wavelengths.approx_equal(b.wavelengths, 1e-6))
    throw InputError(
        fmt::format("basis {} is on {} but {} is on {}; import both with the same --wavelengths "
                    "FIRST:LAST:STEP and learn them again",
                    label_a, a.wavelengths.describe(), label_b, b.wavelengths.describe()));
  const std::size_t most = std::min(a.k(), b.k());
  if (most == 0) throw InputError(fmt::format("basis {} has no components", a.k() == 0 ? label_a : label_b));
  if (o.k > most)
    throw UsageError(fmt::format("-k {}: basis {} has {} components and {} has {}; use -k {} or less", o.k, label_a,
                                 a.k(), label_b, b.k(), most));
  const std::size_t k_max = o.k ? o.k : std::min<std::size_t>(8, most);

  const std::vector<std::vector<double>> degrees = stats::principal_angles_deg(a.components, b.components, k_max);

  if (o.json) {
    Json ks = Json::array(), rows = Json::array();
    for (std::size_t k = 1; k <= k_max; ++k) {
      ks.push_back(k);
      rows.push_back(json_numbers(degrees[k - 1]));
    }
    Json j;
    j["a"] = o.basis_a;
    j["b"] = o.basis_b;
    j["store_a"] = sa.path().string();
    j["store_b"] = sb.path().string();
    j["k"] = std::move(ks);
    j["principal_angles_deg"] = std::move(rows);
    print_json(j);
  } else {
    fmt::print("principal angles (degrees) between the spans of the first k components\n  a: {}\n  b: {}\n", label_a,
               label_b);
    std::string header = "  k";
    for (std::size_t i = 1; i <= k_max; ++i) header += fmt::format("  {:>8}", fmt::format("angle {}", i));
    fmt::print("{}\n", header);
    for (std::size_t k = 1; k <= k_max; ++k) {
      std::string line = fmt::format("{:>3}", k);
      for (double d : degrees[k - 1]) line += fmt::format("  {:>8.3f}", d);
      fmt::print("{}\n", line);
    }
  }
  std::fflush(stdout);

  if (o.plot.empty()) return;
  const std::filesystem::path gnuplot = find_gnuplot();
  if (gnuplot.empty()) {
    std::fprintf(stderr, "gnuplot not found: printed the angles only; install gnuplot-nox for the PNG plots\n");
    return;
  }
  write_plot(gnuplot, o.plot, a, b, label_a, label_b, k_max);
}

}  // namespace

void setup_compare_bases(CLI::App& app) {
  auto o = std::make_shared<CompareBasesOptions>();
  auto* cmd = app.add_subcommand(
      "compare-bases", "Principal angles between the spans of two bases' first k components (k = 1..K), and a plot");
  cmd->add_option("store", o->store, "Store holding basis A (and B unless --store-b)")->required();
  cmd->add_option("basis_a", o->basis_a, "Basis A")->required();
  cmd->add_option("basis_b", o->basis_b, "Basis B")->required();
  cmd->add_option("--store-b", o->store_b, "Store holding basis B");
  cmd->add_option("-k", o->k, "Largest subspace dimension K (default: min(8, components of A, components of B))");
  cmd->add_option("-o,--output", o->plot, "PNG of the first K components of A beside B's (matched, signs aligned)");
  cmd->add_flag("--json", o->json, "Print one JSON object instead of the table");
  cmd->callback([o] { run_compare_bases(*o); });
}

}  // namespace specula::app
