// specula encode: a spectral BRDF grid coded onto a spectral basis (.spc, docs/codec-format.md).
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/acquire/bandwidth.h"
#include "specula/codec/environment.h"
#include "specula/codec/spc_coding.h"
#include "specula/codec/suite.h"
#include "specula/core/brdf_resample.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct EncodeOptions {
  std::string input;
  std::string basis;
  std::size_t k = 0;
  std::size_t extra = 0;
  double max_error = 0.01;
  std::optional<double> step;
  std::optional<double> target_de00;
  std::optional<double> target_p95;
  int trials = 8;
  std::string env = "default";
  double magnitude_scale = 0;
  double grazing_factor = codec::SpcTransformOptions{}.grazing_factor;
  int level = 9;
  std::string samples_rule;
  std::string output;
  bool json = false;
};

codec::SpcTarget target_of(const EncodeOptions& o) {
  return {.de00_mean = o.target_de00.value_or(0),
          .de00_p95 = o.target_p95.value_or(codec::default_p95_target(o.target_de00.value_or(0))),
          .condition_mean = codec::condition_mean_target(o.target_de00.value_or(0)),
          .max_trials = o.trials};
}

std::optional<codec::LightingSuite> suite_of(const EncodeOptions& o, const WavelengthGrid& wavelengths) {
  if (!o.target_de00) return std::nullopt;
  return o.env == "default" ? codec::LightingSuite(wavelengths)
                            : codec::LightingSuite(codec::read_environment(o.env, wavelengths), {});
}

codec::SpcCoding encode_grid(const EncodeOptions& o) {
  const store::Grid grid = load_grid(o.input, "encode");
  if (!o.k && !o.target_de00)
    throw UsageError("encode: give -k with --step or --max-error (only --target-de00 chooses k itself)");
  const codec::SpcBasisSource source = codec::read_basis_source(o.basis, o.extra, "encode: --basis");
  if (!o.step && !o.target_de00)
    return codec::code_grid(grid, source, o.k,
                            {.max_error = o.max_error, .magnitude_scale = o.magnitude_scale, .zstd_level = o.level},
                            o.input);
  codec::SpcTransformOptions options{.grazing_factor = o.grazing_factor, .magnitude_scale = o.magnitude_scale};
  if (o.step) options.step = *o.step;
  const auto suite = suite_of(o, grid.wavelengths);
  const auto target = suite ? std::optional<codec::SpcTargetSearch>({target_of(o), *suite}) : std::nullopt;
  return codec::code_grid(grid, source, o.k, options, target ? &*target : nullptr, o.input);
}

// Format 4: the samples STORE.h5:SAMPLES and the resampling rule (k chosen by leave-one-out for k=auto).
codec::SpcCoding encode_samples(const EncodeOptions& o) {
  const auto spec = store::parse_object_spec(o.input);
  if (!spec || spec->name.empty())
    throw UsageError("encode: with --samples-rule the input is STORE.h5:SAMPLES, not '" + o.input + "'");
  if (!o.target_de00 && !(o.k && o.step))
    throw UsageError("encode: with --samples-rule give --target-de00, or -k with --step");
  const store::Store st = store::Store::open(spec->file);
  const store::SamplesInfo info = st.samples_info(spec->name);
  codec::SpcSamplesOptions options{.rule = brdf::parse_rule(o.samples_rule), .magnitude_scale = o.magnitude_scale};
  if (options.rule.k == 0) options.rule.k = acquire::choose_bandwidth(st, spec->name, options.rule, {}).k;
  if (o.step) options.step = *o.step;
  std::vector<double> angles(4 * info.size);
  std::vector<float> values(info.bands * info.size);
  st.read_samples(spec->name, 0, info.size, angles, values);
  const codec::SpcSampleSet samples{info.wavelengths, angles, values, info.units, 1};
  const codec::SpcBasisSource source = codec::read_basis_source(o.basis, o.extra, "encode: --basis");
  const auto suite = suite_of(o, info.wavelengths);
  const auto target = suite ? std::optional<codec::SpcTargetSearch>({target_of(o), *suite}) : std::nullopt;
  return codec::code_samples(samples, source, o.k, options, target ? &*target : nullptr, o.input);
}

void run_encode(const EncodeOptions& o) {
  if (std::filesystem::path(o.output).extension() != ".spc")
    throw UsageError("encode: -o must name a .spc file, not '" + o.output + "'");
  const auto t0 = std::chrono::steady_clock::now();
  if (o.step && o.target_de00) throw UsageError("encode: give --step or --target-de00, not both");
  if (o.target_p95 && !o.target_de00) throw UsageError("encode: --target-p95 goes with --target-de00");
  const codec::SpcCoding e = o.samples_rule.empty() ? encode_grid(o) : encode_samples(o);
  codec::write_spc_file(o.output, e.bytes);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const codec::SpcTarget target = target_of(o);
  const codec::SpcBoundedOptions bounded{.max_error = o.max_error};
  const bool bounded_method = codec::spc_format_version(e.bytes, o.output) == 1;
  if (o.json) {
    Json j = {{"input", o.input}, {"output", o.output}};
    j.update(codec::spc_coding_json(e, bounded_method ? &bounded : nullptr, o.target_de00 ? &target : nullptr, seconds,
                                    o.output));
    print_json(j);
    return;
  }
  const codec::SpcReport& rep = e.report;
  const double ratio = double(rep.input_bytes) / double(rep.output_bytes);
  fmt::print("encoded {} ({} valid cells) on {} with k = {}: {} bytes, {:.1f}x smaller than float64, in {:.2f} s\n",
             o.input, rep.valid_cells, e.basis.reference, e.basis.k(), rep.output_bytes, ratio, seconds);
  if (e.k_search) {
    fmt::print("k = {} chosen of 1 to {}, the smallest file meeting the target; tried:", e.k_search->k, e.max_k);
    for (const codec::SpcKCandidate& c : e.k_search->candidates)
      fmt::print(" k = {} {};", c.k,
                 !c.searched ? (c.floor_met ? "meets it at the finest step" : "cannot meet it")
                 : c.reached ? fmt::format("{} bytes", c.bytes)
                             : std::string("not met"));
    fmt::print("\n");
  }
  if (e.target)
    fmt::print(
        "{}: step {:.4g} after {} trial codings; under the lighting suite CIEDE2000 mean {:.3f}, 95th "
        "percentile {:.3f}, worst condition {} mean {:.3f} (target {}, {} and {} per condition)\n",
        e.target->reached ? "target met" : "target NOT met (finest step tried)", e.target->step, e.target->trials,
        e.target->de00_mean, e.target->de00_p95, e.target->worst_condition, e.target->worst_mean, *o.target_de00,
        target.de00_p95, 2 * *o.target_de00);
  if (!bounded_method)
    fmt::print(
        "error: RMS {:.4g} 1/sr, max {:.4g} 1/sr; shape: basis residual up to {:.4g}, quantisation up to {:.4g}\n",
        rep.rms_error, rep.max_abs_error, rep.max_shape_residual, rep.max_quantisation_error);
  else
    fmt::print(
        "error: RMS {:.4g} 1/sr, max {:.4g} 1/sr; shape: basis residual up to {:.4g}, quantisation up to {:.4g} (bound "
        "{})\n",
        rep.rms_error, rep.max_abs_error, rep.max_shape_residual, rep.max_quantisation_error, o.max_error);
}

}  // namespace

void setup_encode(CLI::App& app) {
  auto o = std::make_shared<EncodeOptions>();
  auto* cmd = app.add_subcommand("encode", "Code a spectral BRDF grid onto a spectral basis (.spc)");
  cmd->add_option("brdf", o->input,
                  "Spectral grid: STORE.h5:GRID or a .spgrid file (STORE.h5:SAMPLES with --samples-rule)")
      ->required();
  cmd->add_option("--samples-rule", o->samples_rule,
                  "Code scattered samples (format 4) with the rule that resamples them, e.g. "
                  "'weights=wendland,k=auto' (keys mapping, weights, k, power, max_gap; resample's defaults)");
  cmd->add_option("--basis", o->basis, "STORE.h5:BASIS (PCA or NMF) or 'self' (fitted to the grid)")->required();
  cmd->add_option(
         "-k", o->k,
         "Basis spectra per cell; without it --target-de00 chooses the k of the smallest file meeting the target")
      ->check(CLI::Range(1, 1024));
  cmd->add_option("--extra", o->extra,
                  "Spectra fitted to what a learned basis leaves of the grid, added to its k (they travel in the file)")
      ->capture_default_str();
  cmd->add_option("--max-error", o->max_error,
                  "Error target E: magnitude within E (m + s), normalised shape within E per band of its projection")
      ->capture_default_str();
  cmd->add_option("--step", o->step,
                  "Transform coding (format 2) with this quantisation step of log(1 + m / s); shapes and finer bands "
                  "scale from it (docs/codec-format.md)");
  cmd->add_option(
      "--target-de00", o->target_de00,
      "Transform coding with the coarsest step whose CIEDE2000 under the lighting suite (brdf-diff's measure) "
      "has at most this pooled mean, and no condition's mean over twice it");
  cmd->add_option("--target-p95", o->target_p95,
                  "With --target-de00: the most the 95th percentile may be (default 3x the mean)");
  cmd->add_option("--trials", o->trials, "With --target-de00: trial codings at most (2 to 32)")->capture_default_str();
  cmd->add_option("--env", o->env,
                  "With --target-de00: the suite's environment: 'default' (built in) or a lat-long EXR")
      ->capture_default_str();
  cmd->add_option("--grazing-factor", o->grazing_factor,
                  "Transform coding: steps times this at theta_d = 90 deg, rising linearly from 1 at theta_d = 0 "
                  "(1/16 to 16; 1 writes format 2)")
      ->capture_default_str();
  cmd->add_option("--magnitude-scale", o->magnitude_scale,
                  "s of the mapping log(1 + m / s), in the grid's stored units (0: a tenth of the median magnitude)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e30));
  cmd->add_option("--level", o->level, "zstd level")->capture_default_str()->check(CLI::Range(1, 19));
  cmd->add_option("-o,--output", o->output, ".spc file to write")->required();
  cmd->add_flag("--json", o->json, "Print one JSON object (input_bytes, output_bytes, ratio, seconds, errors)");
  cmd->callback([o] { run_encode(*o); });
}

}  // namespace specula::app
