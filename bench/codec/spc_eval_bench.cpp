// Evaluations per second of SpcBrdf's array API against the decoded float32 grid looked up by nearest cell (the
// straightforward grid path: the double-precision MERL lookup, then 31 band values gathered from the band planes;
// and the same with the evaluator's cell index), on the same random direction pairs, same threads, one run. Writes the
// pairs and the decoded grid for the numpy peer (bench/codec/eval_peer.py). Then format 3 against format 2 (the same
// transform coding with grazing factor 1): decoding to coefficients and SpcBrdf evaluation, the two timed alternately,
// best of the repeats. Usage: spc_eval_bench OUT_DIR [PAIRS] [REPEATS] -> JSON lines.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include "specula/codec/spc.h"
#include "specula/codec/spc_eval.h"
#include "specula/core/brdf_geometry.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/brdf_models.h"
#include "specula/core/parallel.h"

namespace {

using namespace specula;
constexpr std::size_t N = brdf::kMerlCells;

void write_raw(const std::filesystem::path& path, const float* data, std::size_t n) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(data), std::streamsize(n * sizeof(float)));
}

// Best of `repeats` wall times of f(), in seconds.
template <class F>
double best_time(int repeats, F&& f) {
  double best = 1e300;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

// Wall seconds of one call of f.
template <class F>
double seconds(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Format 3 against format 2 of the same grid, basis and step (format 2: grazing factor 1), decode to coefficients and
// evaluation alternating (3, 2, 2, 3, ...) so that load from other processes falls on both alike; best of `repeats`.
void format_ab(const store::Grid& grid, std::span<const float> wi, std::span<const float> wo, std::span<float> out,
               int repeats) {
  const std::size_t n = wi.size() / 3;
  for (const std::size_t k : {3, 6}) {
    const codec::SpcBasis basis = codec::self_basis(grid, k);
    const std::vector<std::uint8_t> files[2] = {
        codec::encode_spc(grid, basis, codec::SpcTransformOptions{.step = 0.05}),
        codec::encode_spc(grid, basis, {.step = 0.05, .grazing_factor = 1})};
    const codec::SpcBrdf f[2] = {codec::SpcBrdf(codec::decode_spc_coefficients(files[0], "v3.spc")),
                                 codec::SpcBrdf(codec::decode_spc_coefficients(files[1], "v2.spc"))};
    double decode[2] = {1e300, 1e300}, eval[2] = {1e300, 1e300};
    for (int r = 0; r < repeats; ++r)
      for (const int v : {r % 2, 1 - r % 2}) {
        decode[v] = std::min(decode[v], seconds([&] { (void)codec::decode_spc_coefficients(files[v], "x.spc"); }));
        eval[v] = std::min(eval[v], seconds([&] { f[v].evaluate(wi, wo, out); }));
      }
    const double mb = double(grid.brdf.size()) * 4 / 1e6;  // the float32 grid, as decode --json counts
    fmt::print(
        "{{\"ab_k\": {}, \"versions\": [{}, {}], \"bytes\": [{}, {}], \"decode_mb_per_s\": [{:.4g}, {:.4g}], "
        "\"eval_per_s\": [{:.4g}, {:.4g}]}}\n",
        k, codec::spc_format_version(files[0], "v3"), codec::spc_format_version(files[1], "v2"), files[0].size(),
        files[1].size(), mb / decode[0], mb / decode[1], double(n) / eval[0], double(n) / eval[1]);
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    fmt::print(stderr, "usage: spc_eval_bench OUT_DIR [PAIRS] [REPEATS]\n");
    return 2;
  }
  const std::filesystem::path out_dir = argv[1];
  const std::size_t n = argc > 2 ? std::stoul(argv[2]) : 2'000'000;
  const int repeats = argc > 3 ? std::stoi(argv[3]) : 5;
  std::filesystem::create_directories(out_dir);
  const WavelengthGrid wl = WavelengthGrid::range(400, 700, 10);
  const std::size_t b = wl.size();
  store::Grid grid;
  grid.wavelengths = wl;
  grid.brdf.resize(b * N);
  brdf::evaluate_grid(*brdf::make_material("red-plastic", wl), grid.brdf);

  // Directions uniform over the upper hemisphere, independently for wi and wo.
  std::vector<float> wi(3 * n), wo(3 * n);
  std::mt19937_64 rng(19);
  std::uniform_real_distribution<double> u(0, 1);
  for (std::size_t i = 0; i < 2 * n; ++i) {
    const double ct = u(rng), st = std::sqrt(1 - ct * ct), p = 2 * std::numbers::pi * u(rng);
    float* d = (i < n ? wi.data() + 3 * i : wo.data() + 3 * (i - n));
    d[0] = float(st * std::cos(p)), d[1] = float(st * std::sin(p)), d[2] = float(ct);
  }
  write_raw(out_dir / "wi.f32", wi.data(), wi.size());
  write_raw(out_dir / "wo.f32", wo.data(), wo.size());

  std::vector<float> out(n * b), peer(n * b);
  for (const std::size_t k : {3, 6}) {
    codec::SpcCoefficients c = codec::decode_spc_coefficients(
        codec::encode_spc(grid, codec::self_basis(grid, k), {.max_error = 0.01}), "bench.spc");
    const store::Grid decoded = codec::expand_spc(c);
    const codec::SpcBrdf f(std::move(c));
    const double t_eval = best_time(repeats, [&] { f.evaluate(wi, wo, out); });
    // The peer: the decoded grid's nearest cell by the double lookup, its band values (no data as 0) times scale.
    const float scale = float(decoded.scale);
    const double t_grid = best_time(repeats, [&] {
      parallel_for(
          n,
          [&](std::size_t i) {
            const Eigen::Vector3d a(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                o(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
            const std::size_t cell = brdf::merl_index(brdf::merl_cell(brdf::half_diff(a, o)));
            for (std::size_t band = 0; band < b; ++band)
              peer[i * b + band] = std::max(decoded.brdf[band * N + cell], 0.0f) * scale;
          },
          4096);
    });
    // The same grid with the evaluator's cell index (merl_indices), to separate the layout from the lookup.
    const double t_grid_fast = best_time(repeats, [&] {
      parallel_for((n + 4095) / 4096, [] { return std::vector<std::uint32_t>(4096); },
                   [&](std::size_t block, std::vector<std::uint32_t>& cells) {
                     const std::size_t first = block * 4096, m = std::min<std::size_t>(4096, n - first);
                     codec::merl_indices(std::span(wi).subspan(3 * first, 3 * m),
                                         std::span(wo).subspan(3 * first, 3 * m), std::span(cells).first(m));
                     for (std::size_t i = 0; i < m; ++i)
                       for (std::size_t band = 0; band < b; ++band)
                         peer[(first + i) * b + band] = std::max(decoded.brdf[band * N + cells[i]], 0.0f) * scale;
                   });
    });
    double max_diff = 0, max_value = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      max_diff = std::max(max_diff, double(std::abs(out[i] - peer[i])));
      max_value = std::max(max_value, double(peer[i]));
    }
    if (k == 3) {
      write_raw(out_dir / "grid.f32", decoded.brdf.data(), decoded.brdf.size());
      std::ofstream(out_dir / "grid.json") << fmt::format("{{\"bands\": {}, \"scale\": {}}}\n", b, decoded.scale);
    }
    fmt::print(
        "{{\"k\": {}, \"pairs\": {}, \"spc_eval_per_s\": {:.4g}, \"grid_lookup_per_s\": {:.4g}, "
        "\"grid_fast_index_per_s\": {:.4g}, "
        "\"memory_bytes\": {}, \"grid_bytes\": {}, \"max_abs_diff\": {:.3g}, \"max_value\": {:.3g}}}\n",
        k, n, double(n) / t_eval, double(n) / t_grid, double(n) / t_grid_fast, f.memory_bytes(),
        decoded.brdf.size() * sizeof(float), max_diff, max_value);
    std::fflush(stdout);
  }
  format_ab(grid, wi, wo, out, repeats);
  return 0;
}
