#include "specula/acquire/holdout.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "specula/acquire/spectral.h"
#include "specula/core/error.h"
#include "specula/core/wavelengths.h"

namespace specula::acquire {

namespace fs = std::filesystem;

std::vector<HoldoutPatch> holdout_chart(const store::Collection& table, std::span<const double> bands, int width,
                                        int height) {
  const std::string source = table.provenance.source_file.empty() ? "held-out patches" : table.provenance.source_file;
  const std::size_t n = table.size(), nb = table.bands();
  if (n == 0 || nb < 2) throw InputError(source + ": no reflectance spectra on two or more wavelengths");
  for (std::size_t i = 0; i < n * nb; ++i)
    if (!(table.values[i] >= 0))
      throw InputError(fmt::format("{}: patch '{}' has a negative reflectance at {} nm", source, table.names[i / nb],
                                   table.wavelengths[i % nb]));
  if (bands.empty() || table.wavelengths.front() > bands.front() || table.wavelengths.back() < bands.back())
    throw InputError(fmt::format("{}: tabulated on {}-{} nm, which does not cover the bands {}-{} nm", source,
                                 table.wavelengths.front(), table.wavelengths.back(), bands.front(), bands.back()));
  const auto cols = std::size_t(std::ceil(std::sqrt(double(n) * width / height)));
  const std::size_t rows = (n + cols - 1) / cols;
  const int cw = width / int(cols), ch = height / int(rows);
  if (cw < 8 || ch < 8)
    throw InputError(fmt::format("{}: {} patches do not fit on a {} x {} image (each needs 8 x 8 pixels)", source, n,
                                 width, height));
  const Eigen::MatrixXd to_bands =
      resample_matrix(table.wavelengths, WavelengthGrid(std::vector<double>(bands.begin(), bands.end())), source);
  std::vector<HoldoutPatch> patches;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::VectorXd r(static_cast<Eigen::Index>(nb));
    for (std::size_t b = 0; b < nb; ++b) r[Eigen::Index(b)] = table.values[i * nb + b];
    const Eigen::VectorXd on_bands = to_bands * r;
    // A gap of a sixth of a cell between patches, as on a printed chart.
    const int u = int(i % cols) * cw, v = int(i / cols) * ch, mu = std::max(1, cw / 6), mv = std::max(1, ch / 6);
    patches.push_back({table.names[i], std::vector<double>(on_bands.data(), on_bands.data() + on_bands.size()), u + mu,
                       v + mv, u + cw - mu, v + ch - mv});
  }
  return patches;
}

std::vector<HoldoutReport> recover_holdout(const Capture& cap, const fs::path& dir, const Calibration& c,
                                           const PipelineOptions& o) {
  if (cap.holdout.empty()) return {};
  std::vector<HdrImage> hdr;
  for (std::size_t b = 0; b < cap.channels(); ++b)
    hdr.push_back(merge_series(cap, dir, ImageKind::holdout, -1, -1, int(b), o.hdr));
  std::vector<HoldoutReport> reports;
  Eigen::VectorXd h;
  for (const HoldoutPatch& patch : cap.holdout) {
    HoldoutReport r;
    r.name = patch.name;
    r.truth = Eigen::Map<const Eigen::VectorXd>(patch.reflectance.data(), Eigen::Index(patch.reflectance.size()));
    r.recovered = Eigen::VectorXd::Zero(r.truth.size());
    double pixel_rms = 0;
    // The central half of the region: a printed patch's edges blur into its neighbours.
    const int qu = (patch.u1 - patch.u0) / 4, qv = (patch.v1 - patch.v0) / 4;
    for (int v = patch.v0 + qv; v < patch.v1 - qv; ++v)
      for (int u = patch.u0 + qu; u < patch.u1 - qu; ++u) {
        const std::size_t p = std::size_t(v) * std::size_t(cap.width) + std::size_t(u);
        if (pixel_readings(hdr, p, c.spatial, o, h) != Reject::count) {
          ++r.rejected;
          continue;
        }
        const Eigen::VectorXd f = recover_spectrum(c.spectral, h);
        r.recovered += f;
        pixel_rms += spectral_rms(f, r.truth);
        ++r.pixels;
      }
    if (r.pixels) {
      r.recovered /= double(r.pixels);
      r.rms = spectral_rms(r.recovered, r.truth);
      r.pixel_rms = pixel_rms / double(r.pixels);
    }
    reports.push_back(std::move(r));
  }
  return reports;
}

}  // namespace specula::acquire
