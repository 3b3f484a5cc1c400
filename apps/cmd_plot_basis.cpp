// specula plot-basis (reference §7.3, figures 7.2 and 7.3; §7.4, figure 7.6): a basis's eigenvalues and
// first components as CSV tables, or several bases side by side, and as PNG plots drawn by gnuplot when it
// is installed.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/gnuplot.h"
#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/stats/basis_tables.h"
#include "specula/store/store.h"

namespace specula::app {

namespace {

struct PlotBasisOptions {
  std::string store;
  std::vector<std::string> bases;
  std::string output;
  std::size_t components = 8;
};

// Writes `text` to `path` atomically.
void write_text(const std::filesystem::path& path, const std::string& text) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary);
    f << text;
    f.flush();
    if (!f) throw LibraryError(path.string() + ": cannot write: " + std::strerror(errno));
  }
  out.commit();
}

// Several bases (e.g. NMF for k = 3..8, figure 7.6): one CSV each and one PNG with a panel per basis.
void plot_panel(const store::Store& s, const PlotBasisOptions& o, const std::filesystem::path& dir) {
  std::vector<store::Basis> bases;
  for (const auto& name : o.bases) bases.push_back(s.read_basis(name));
  std::string script;
  const std::size_t cols = bases.size() <= 4 ? 2 : 3, rows = (bases.size() + cols - 1) / cols;
  for (std::size_t i = 0; i < bases.size(); ++i) {
    const store::Basis& b = bases[i];
    if (b.k() == 0) throw InputError(fmt::format("{}: basis '{}' has no components", s.label(), o.bases[i]));
    if (!b.wavelengths.approx_equal(bases.front().wavelengths))
      throw InputError(fmt::format("{}: basis {} has {}, basis {} has {}; a panel needs bases on one grid", s.label(),
                                   o.bases[i], b.wavelengths.describe(), o.bases.front(),
                                   bases.front().wavelengths.describe()));
    write_text(dir / (o.bases[i] + "-components.csv"), stats::components_csv(b, b.k()));
    script += fmt::format("$B{} << EOD\n{}EOD\n", i, stats::components_rows(b, b.k(), ' '));
  }
  const std::filesystem::path gnuplot = find_gnuplot();
  if (gnuplot.empty()) {
    std::fprintf(stderr, "gnuplot not found: wrote the CSV files only; install gnuplot-nox for the PNG plots\n");
    return;
  }
  script += fmt::format("set multiplot layout {},{} title {} noenhanced\n", rows, cols,
                        gnuplot_quote(fmt::format("Basis spectra in {}", s.label())));
  script += "set grid\nset xzeroaxis lt -1 lw 0.5\nunset key\nset xlabel 'wavelength (nm)'\n";
  script += fmt::format("set xrange [{}:{}]\n", bases.front().wavelengths.front(), bases.front().wavelengths.back());
  for (std::size_t i = 0; i < bases.size(); ++i) {
    const store::Basis& b = bases[i];
    script += "set title " +
              gnuplot_quote(fmt::format("{} ({}, k = {}, {} spectra)", o.bases[i], b.method, b.k(), b.n)) +
              " noenhanced\n";
    script += fmt::format("plot for [i=2:{}] $B{} using 1:i with lines lw 2\n", b.k() + 1, i);
  }
  script += "unset multiplot\n";
  plot_png(gnuplot, dir / "panel.png", gnuplot_png_terminal(int(500 * cols), int(380 * rows)), script);
}

void run_plot_basis(const PlotBasisOptions& o) {
  if (o.components < 1) throw UsageError("--components must be at least 1");
  const store::Store s = store::Store::open(o.store);
  const std::filesystem::path dir = o.output;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!std::filesystem::is_directory(dir))
    throw InputError(fmt::format("-o {}: not a directory and cannot be created{}{}", dir.string(), ec ? ": " : "",
                                 ec ? ec.message() : ""));
  if (o.bases.size() > 1) {
    plot_panel(s, o, dir);
    return;
  }
  const std::string& name = o.bases.front();
  const store::Basis b = s.read_basis(name);
  if (b.k() == 0) throw InputError(fmt::format("{}: basis '{}' has no components", s.label(), name));
  const std::size_t n = std::min(o.components, b.k());
  const bool has_eigenvalues = b.eigenvalues.size() > 0;

  if (has_eigenvalues) write_text(dir / "eigenvalues.csv", stats::eigenvalues_csv(b));
  write_text(dir / "components.csv", stats::components_csv(b, n));

  const std::filesystem::path gnuplot = find_gnuplot();
  if (gnuplot.empty()) {
    std::fprintf(stderr, "gnuplot not found: wrote the CSV files only; install gnuplot-nox for the PNG plots\n");
    return;
  }
  const std::string method = b.method == "nmf" ? "NMF" : "principal";
  const std::string label = fmt::format("basis {} in {} ({} spectra)", name, s.label(), b.n);
  if (has_eigenvalues) {
    std::string script = "$EV << EOD\n" + stats::eigenvalues_rows(b) + "EOD\n";
    script += "set title " + gnuplot_quote("Eigenvalue magnitudes of " + label) + " noenhanced\n";
    script += "set logscale y\nset format y '10^{%L}'\nset grid\nunset key\n";
    script += "set xlabel 'component index'\nset ylabel '|eigenvalue| (variance along the component)'\n";
    script += fmt::format("set xrange [0.5:{}]\n", double(b.eigenvalues.size()) + 0.5);
    script += "plot $EV using 1:(abs($2) > 0 ? abs($2) : 1/0) with linespoints pt 7 ps 0.8 lc rgb '#1f4e99'\n";
    plot_png(gnuplot, dir / "eigenvalues.png", gnuplot_png_terminal(900, 600), script);
  }
  std::string script = "$C << EOD\n" + stats::components_rows(b, n, ' ') + "EOD\n";
  script +=
      "set title " + gnuplot_quote(fmt::format("First {} {} components of {}", n, method, label)) + " noenhanced\n";
  script += "set grid\nset xzeroaxis lt -1 lw 0.5\nset key outside right top\n";
  script += "set xlabel 'wavelength (nm)'\nset ylabel 'component weight'\n";
  script += fmt::format("set xrange [{}:{}]\n", b.wavelengths.front(), b.wavelengths.back());
  script += fmt::format("plot for [i=2:{}] $C using 1:i with lines lw 2 title sprintf('c%d', i-1)\n", n + 1);
  plot_png(gnuplot, dir / "components.png", gnuplot_png_terminal(1000, 600), script);
}

}  // namespace

void setup_plot_basis(CLI::App& app) {
  auto o = std::make_shared<PlotBasisOptions>();
  auto* cmd = app.add_subcommand(
      "plot-basis",
      "Write a basis's eigenvalues and first components as CSV, and as PNG plots when gnuplot is installed; with "
      "several bases (e.g. NMF for k = 3..8, figure 7.6) one CSV each and panel.png");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("basis", o->bases, "Basis name(s)")->required();
  cmd->add_option("-o,--output", o->output,
                  "Directory for eigenvalues.csv, components.csv and their PNGs (several bases: <name>-components.csv, "
                  "panel.png)")
      ->required();
  cmd->add_option("--components", o->components, "Components to write and plot (at most the basis's own)")
      ->capture_default_str();
  cmd->callback([o] { run_plot_basis(*o); });
}

}  // namespace specula::app
