// specula decode: a .spc file (docs/codec-format.md) back into a spectral grid, a store grid or an RGB .binary.
#include <fmt/format.h>
#include <omp.h>

#include <chrono>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/codec/spc.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct DecodeOptions {
  std::string input;
  std::string output;
  bool replace = false;
  bool json = false;
};

void run_decode(const DecodeOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto bytes = codec::read_spc_file(o.input);
  const auto t1 = std::chrono::steady_clock::now();
  const codec::SpcCoefficients coefficients =
      codec::decode_spc_coefficients(bytes, std::filesystem::path(o.input).filename().string());
  const auto t_coefficients = std::chrono::steady_clock::now();
  const store::Grid grid = codec::expand_spc(coefficients);
  const auto t2 = std::chrono::steady_clock::now();
  const std::string what = save_grid(grid, o.output, o.replace, "decode");
  const double decode_s = std::chrono::duration<double>(t2 - t1).count();
  const double coefficients_s = std::chrono::duration<double>(t_coefficients - t1).count();
  const double out_mb = double(grid.brdf.size()) * 4 / 1e6;
  if (o.json) {
    Json j;
    j["input"] = o.input;
    j["output"] = o.output;
    j["input_bytes"] = bytes.size();
    j["output_bytes_float32"] = grid.brdf.size() * 4;
    j["decode_seconds"] = decode_s;
    j["decode_mb_per_s"] = out_mb / decode_s;
    j["coefficients_seconds"] = coefficients_s;
    j["coefficients_mb_per_s"] = out_mb / coefficients_s;
    j["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    j["threads"] = omp_get_max_threads();
    print_json(j);
    return;
  }
  fmt::print("decoded {} into {}: {:.0f} MB of float32 in {:.3f} s ({:.0f} MB/s; its coefficient form in {:.3f} s)\n",
             o.input, what, out_mb, decode_s, out_mb / decode_s, coefficients_s);
}

}  // namespace

void setup_decode(CLI::App& app) {
  auto o = std::make_shared<DecodeOptions>();
  auto* cmd = app.add_subcommand("decode", "Decode a .spc file into a spectral grid");
  cmd->add_option("spc", o->input, ".spc file")->required();
  cmd->add_option("-o,--output", o->output, "STORE.h5:GRID, a .spgrid file, or an RGB .binary (CIE 1931, D65)")
      ->required();
  cmd->add_flag("--replace", o->replace, "Replace a grid of the same name in the store");
  cmd->add_flag("--json", o->json,
                "Print one JSON object (sizes, decode seconds and MB/s, to the grid and to the coefficient form)");
  cmd->callback([o] { run_decode(*o); });
}

}  // namespace specula::app
