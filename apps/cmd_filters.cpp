// specula filters design: K broadband transmission curves for a spectral basis (the reference's chapter 8), from
// its NMF components or optimised for the expected reconstruction error under camera noise (acquire/filter_design.h),
// written as a filter CSV for `simulate-capture --filters`, with a PNG of the curves and the expected error on
// held-out spectra.
#include <fmt/format.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "apps/gnuplot.h"
#include "specula/acquire/filter_design.h"
#include "specula/acquire/filter_report.h"
#include "specula/core/error.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct FiltersDesignOptions {
  std::string store, basis, train, test, output, plot, method = "optimal", solve = "wiener";
  acquire::FilterDesignOptions design;
  bool json = false;
};

void plot_filters(const std::filesystem::path& gnuplot, const std::filesystem::path& target,
                  const acquire::FilterDesign& d, const std::string& title) {
  std::string script = "$F << EOD\n";
  const acquire::FilterSet& f = d.filters;
  for (std::size_t i = 0; i < f.nm.size(); ++i) {
    script += fmt::format("{}", f.nm[i]);
    for (const auto& t : f.transmission) script += fmt::format(" {:.5f}", t[i]);
    script += "\n";
  }
  script += "EOD\nset grid\nset key outside right\nset xlabel 'wavelength (nm)'\nset ylabel 'transmission'\n";
  script += "set yrange [0:1.05]\nset title " + gnuplot_quote(title) + " noenhanced\nplot ";
  for (std::size_t k = 0; k < f.size(); ++k)
    script += fmt::format("{}$F using 1:{} with lines lw 2 title {} noenhanced", k ? ", " : "", k + 2,
                          gnuplot_quote(f.names[k]));
  plot_png(gnuplot, target, gnuplot_png_terminal(900, 500), script + "\n");
}

void run_filters_design(FiltersDesignOptions o) {
  o.design.method = acquire::parse_filter_method(o.method);
  o.design.solve = acquire::parse_filter_solve(o.solve);
  acquire::check_filter_design(o.design);
  std::filesystem::path gnuplot;
  if (!o.plot.empty()) {
    gnuplot = find_gnuplot();
    if (gnuplot.empty())
      throw UsageError("filters design: --plot draws with gnuplot; install it (Debian: gnuplot-nox)");
  }
  const acquire::FilterDesign d =
      acquire::design_filters(store::Store::open(o.store), o.basis, o.train, o.test, o.design);
  acquire::write_filters_csv(o.output, d.filters);
  const std::string title = fmt::format("{} filters ({}) for basis {}: held-out RMS {:.4f}", d.filters.size(), o.method,
                                        o.basis, d.held_out.rms_mean);
  if (!o.plot.empty()) plot_filters(gnuplot, o.plot, d, title);
  if (o.json) {
    Json j = {{"output", o.output}};
    j.update(acquire::filter_design_json(d, o.design));
    print_json(j);
    return;
  }
  fmt::print("wrote {} {} filters to {}{}\n", d.filters.size(), o.method, o.output,
             o.plot.empty() ? "" : " (curves in " + o.plot + ")");
  fmt::print("expected spectral RMS (eq 4.8) at noise {}: {:<40} mean {:.4f}  median {:.4f}  max {:.4f}\n",
             o.design.noise, "training " + d.training_name, d.training.rms_mean, d.training.rms_median,
             d.training.rms_max);
  fmt::print("{:>{}}{:<40} mean {:.4f}  median {:.4f}  max {:.4f}  (noise alone {:.4f})\n", "",
             fmt::format("expected spectral RMS (eq 4.8) at noise {}: ", o.design.noise).size(),
             "held out " + d.held_out_name, d.held_out.rms_mean, d.held_out.rms_median, d.held_out.rms_max,
             d.held_out.noise_rms);
}

}  // namespace

void setup_filters(CLI::App& app) {
  auto* cmd = app.add_subcommand("filters", "Broadband filters for a filter-wheel capture");
  cmd->require_subcommand(1);
  auto o = std::make_shared<FiltersDesignOptions>();
  auto* d = cmd->add_subcommand("design", "Design K filters for a spectral basis (CSV, plot, expected error)");
  d->add_option("store", o->store, "Store with the basis and the spectra")->required();
  d->add_option("--basis", o->basis, "The basis the spectra are reconstructed in (pca or nmf)")->required();
  d->add_option("-k", o->design.k, "Number of filters")->capture_default_str();
  d->add_option("-o,--output", o->output, "Filter CSV to write")->required();
  d->add_option("--method", o->method, "nmf (smoothed NMF components) or optimal (expected error)")
      ->capture_default_str();
  d->add_option("--noise", o->design.noise, "Camera noise relative to each filter's white reading")
      ->capture_default_str();
  d->add_flag(
      "--equal-exposure", [o](std::int64_t) { o->design.per_filter_exposure = false; },
      "Noise relative to an open filter's white reading (every filter exposed alike)");
  d->add_option("--min-throughput", o->design.min_throughput,
                "Light (fraction of an open filter's) below which a filter's exposure is capped: its noise floor")
      ->capture_default_str();
  d->add_option("--solve", o->solve, "wiener (the training spectra's second moment as prior) or ridge (in the basis)")
      ->capture_default_str();
  d->add_option(
       "--colour-weight", o->design.colour_weight,
       "optimal: weight of the expected XYZ error under D65 and A against the spectral error (0: spectral only)")
      ->capture_default_str();
  d->add_option("--ridge", o->design.ridge, "Regularisation of the solve (relative to the system's trace)")
      ->capture_default_str();
  d->add_option("--peak", o->design.peak, "Largest transmission of a curve")->capture_default_str();
  d->add_option("--light-kelvin", o->design.light_kelvin, "The light the design assumes (a blackbody)")
      ->capture_default_str();
  d->add_option("--train", o->train, "Training collection (default: the one the basis was learned from)");
  d->add_option("--test", o->test, "Held-out collection (default: every fifth training spectrum)");
  d->add_option("--plot", o->plot, "PNG of the curves");
  d->add_flag("--json", o->json, "Print one JSON object");
  d->callback([o] { run_filters_design(*o); });
}

}  // namespace specula::app
